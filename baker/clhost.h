/* clhost.h: the OpenCL host layer.
 *
 * Chooses a platform and device (PoCL by default, so a bake runs the same on
 * any machine; `--device` picks another), builds programs from the kernels
 * embedded at build time (the .cl files of kernels/ with their headers, `#include "x.h"`
 * resolved from the same set) with `-D` options, prints the build log on
 * failure, and caches program binaries on disk keyed by a hash of the full
 * expanded source, the options and the device. Every OpenCL call goes through
 * CLH_CHECK, which reports the call text, file:line and the error's name. */
#ifndef BAKER_CLHOST_H
#define BAKER_CLHOST_H

#ifndef CL_TARGET_OPENCL_VERSION
#define CL_TARGET_OPENCL_VERSION 120
#endif
#include <CL/cl.h>
#include "base/common.h"
#include "clsource.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What clh_build did, so callers and tests can see the cache at work. */
typedef struct clh_build_stats {
  unsigned cache_hits;    /* programs loaded from the binary cache */
  unsigned cache_misses;  /* cache on, but no usable entry */
  unsigned source_builds; /* programs compiled from source */
  int last_hit;           /* the latest build came from the cache (2: a kept program) */
  double last_ms;         /* wall time of the latest build */
  uint64_t last_key;      /* its cache key */
  unsigned kept_hits;     /* programs this context had built before (no build at all) */
} clh_build_stats_t;

/* Programs a context with keep_programs set keeps after building them, by
 * cache key (the expanded source, options and device): a batch of frames
 * (baker/frame_reuse.h) builds each kernel once. */
#define CLH_KEPT_PROGRAMS 8

typedef struct clh_context {
  cl_platform_id platform;
  cl_device_id device;
  cl_context context;
  cl_command_queue queue;
  char platform_name[256];
  char device_name[256];
  char driver_version[128];
  cl_uint compute_units;
  cl_ulong global_mem;
  cl_ulong max_alloc;
  int has_int64_atomics;   /* cl_khr_int64_base_atomics */
  int is_cpu;
  int exact_div_sqrt;      /* CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT: builds ask for it */
  clh_build_stats_t stats;
  int keep_programs;         /* set after clh_init: keep built programs (below) */
  struct { uint64_t key; cl_program program; } kept[CLH_KEPT_PROGRAMS];
  int kept_count, kept_next; /* filled; the slot replaced next when full */
  /* two pinned staging buffers for large copies to and from a discrete
   * device (baker/clcopy.c), made on first use, mapped while they live */
  cl_mem stage[2];
  void *stage_map[2];
} clh_context_t;

const char *clh_error_name(cl_int code);

/* Wraps an OpenCL call: on failure fills `err` (BK_ERR_RUNTIME) with the call
 * text, file:line and error name, then jumps to `label` (the function's one
 * cleanup block). */
#define CLH_CHECK(call, err, label)                                              \
  do {                                                                           \
    cl_int clh_rc_ = (call);                                                     \
    if (clh_rc_ != CL_SUCCESS) {                                                 \
      bk_fail((err), BK_ERR_RUNTIME, "OpenCL: %s failed at %s:%d: %s", #call,   \
              __FILE__, __LINE__, clh_error_name(clh_rc_));                      \
      goto label;                                                                \
    }                                                                            \
  } while (0)

/* device_spec: NULL or "" for the default (PoCL if present, else the first
 * device), "list" is handled by the caller via clh_list_devices, otherwise
 * "P:D" (platform and device indices), "gpu"/"cpu"/"accelerator" (the first
 * device of that type) or a case-insensitive substring of the platform name,
 * platform vendor or device name. A spec matching nothing is BK_ERR_INPUT
 * with the list of devices. No platform at all gives a clear BK_ERR_RUNTIME. */
int clh_init(clh_context_t *cl, const char *device_spec, bk_error_t *err);
void clh_release(clh_context_t *cl);
void clh_list_devices(FILE *out);

/* Builds kernels/<file> with `options` (e.g. "-DHAS_REFRACTION=1"). Uses the
 * binary cache in $BAKER_CACHE_DIR, else $XDG_CACHE_HOME/baker, else
 * ~/.cache/baker (BAKER_NO_CACHE=1 turns it off). */
int clh_build(clh_context_t *cl, const char *file, const char *options, cl_program *out,
              bk_error_t *err);

/* The binary cache's directory (as clh_build chooses it) into out; 0 when the
 * cache is off. Entries beyond $BAKER_CACHE_MAX_MB go, least recently used
 * first (clcache.h). */
int clh_cache_dir(char *out, size_t len);

/* What clh_build does once it has the text: `name` is only used in messages
 * ("kernels/x.cl"); includes resolve from the embedded kernels. Lets tests
 * build a source that is not in kernels/. */
int clh_build_source(clh_context_t *cl, const char *name, const char *text, const char *options,
                     cl_program *out, bk_error_t *err);

#ifdef __cplusplus
}
#endif
#endif
