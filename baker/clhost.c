/* clhost.c: OpenCL platform/device choice, program builds (their sources
 * expanded by clsource.c) and the on-disk binary cache. */
#define _POSIX_C_SOURCE 200809L
#include "clhost.h"
#include "clenv.h"

#include <ctype.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "clcache.h"

#ifndef CL_PLATFORM_NOT_FOUND_KHR
#define CL_PLATFORM_NOT_FOUND_KHR -1001
#endif

/* Enough for any machine we know of; more are ignored, not an error. */
#define CLH_MAX_PLATFORMS 16
#define CLH_MAX_DEVICES 64
/* Room kept in bk_error_t.msg for the text around a build log. */
#define CLH_LOG_RESERVE 400

/* --- error names ------------------------------------------------------------ */

const char *clh_error_name(cl_int code) {
  switch (code) {
#define N(c) case c: return #c;
    N(CL_SUCCESS)
    N(CL_DEVICE_NOT_FOUND)
    N(CL_DEVICE_NOT_AVAILABLE)
    N(CL_COMPILER_NOT_AVAILABLE)
    N(CL_MEM_OBJECT_ALLOCATION_FAILURE)
    N(CL_OUT_OF_RESOURCES)
    N(CL_OUT_OF_HOST_MEMORY)
    N(CL_PROFILING_INFO_NOT_AVAILABLE)
    N(CL_MEM_COPY_OVERLAP)
    N(CL_IMAGE_FORMAT_MISMATCH)
    N(CL_IMAGE_FORMAT_NOT_SUPPORTED)
    N(CL_BUILD_PROGRAM_FAILURE)
    N(CL_MAP_FAILURE)
    N(CL_MISALIGNED_SUB_BUFFER_OFFSET)
    N(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST)
    N(CL_COMPILE_PROGRAM_FAILURE)
    N(CL_LINKER_NOT_AVAILABLE)
    N(CL_LINK_PROGRAM_FAILURE)
    N(CL_DEVICE_PARTITION_FAILED)
    N(CL_KERNEL_ARG_INFO_NOT_AVAILABLE)
    N(CL_INVALID_VALUE)
    N(CL_INVALID_DEVICE_TYPE)
    N(CL_INVALID_PLATFORM)
    N(CL_INVALID_DEVICE)
    N(CL_INVALID_CONTEXT)
    N(CL_INVALID_QUEUE_PROPERTIES)
    N(CL_INVALID_COMMAND_QUEUE)
    N(CL_INVALID_HOST_PTR)
    N(CL_INVALID_MEM_OBJECT)
    N(CL_INVALID_IMAGE_FORMAT_DESCRIPTOR)
    N(CL_INVALID_IMAGE_SIZE)
    N(CL_INVALID_SAMPLER)
    N(CL_INVALID_BINARY)
    N(CL_INVALID_BUILD_OPTIONS)
    N(CL_INVALID_PROGRAM)
    N(CL_INVALID_PROGRAM_EXECUTABLE)
    N(CL_INVALID_KERNEL_NAME)
    N(CL_INVALID_KERNEL_DEFINITION)
    N(CL_INVALID_KERNEL)
    N(CL_INVALID_ARG_INDEX)
    N(CL_INVALID_ARG_VALUE)
    N(CL_INVALID_ARG_SIZE)
    N(CL_INVALID_KERNEL_ARGS)
    N(CL_INVALID_WORK_DIMENSION)
    N(CL_INVALID_WORK_GROUP_SIZE)
    N(CL_INVALID_WORK_ITEM_SIZE)
    N(CL_INVALID_GLOBAL_OFFSET)
    N(CL_INVALID_EVENT_WAIT_LIST)
    N(CL_INVALID_EVENT)
    N(CL_INVALID_OPERATION)
    N(CL_INVALID_GL_OBJECT)
    N(CL_INVALID_BUFFER_SIZE)
    N(CL_INVALID_MIP_LEVEL)
    N(CL_INVALID_GLOBAL_WORK_SIZE)
    N(CL_INVALID_PROPERTY)
    N(CL_INVALID_IMAGE_DESCRIPTOR)
    N(CL_INVALID_COMPILER_OPTIONS)
    N(CL_INVALID_LINKER_OPTIONS)
    N(CL_INVALID_DEVICE_PARTITION_COUNT)
#undef N
  case CL_PLATFORM_NOT_FOUND_KHR: return "CL_PLATFORM_NOT_FOUND_KHR";
  default: break;
  }
  static _Thread_local char buf[48];
  snprintf(buf, sizeof buf, "unknown OpenCL error %d", (int)code);
  return buf;
}

/* --- device enumeration ----------------------------------------------------- */

typedef struct clh_dev_entry {
  cl_platform_id platform;
  cl_device_id device;
  int pi, di;
  char pname[256], pvendor[256], dname[256];
  cl_device_type type;
} clh_dev_entry_t;

static const char *no_platform_msg =
    "no OpenCL platform found: install pocl-opencl-icd (CPU) or a GPU driver's ICD; "
    "see `clinfo`";

static int is_pocl(const clh_dev_entry_t *e) {
  return strstr(e->pname, "Portable Computing Language") || strstr(e->pname, "pocl") ||
         strstr(e->pvendor, "pocl");
}

/* Every device of every platform, in platform order. */
static int clh_enumerate(clh_dev_entry_t *list, int cap, int *count, bk_error_t *err) {
  cl_platform_id plats[CLH_MAX_PLATFORMS];
  cl_uint np = 0;
  *count = 0;
  clh_prepare_env(); /* PoCL reads POCL_CACHE_DIR when first touched */
  cl_int rc = clGetPlatformIDs(CLH_MAX_PLATFORMS, plats, &np);
  if (rc == CL_PLATFORM_NOT_FOUND_KHR || (rc == CL_SUCCESS && np == 0))
    return bk_fail(err, BK_ERR_RUNTIME, "%s", no_platform_msg);
  if (rc != CL_SUCCESS)
    return bk_fail(err, BK_ERR_RUNTIME, "OpenCL: clGetPlatformIDs failed: %s", clh_error_name(rc));
  if (np > CLH_MAX_PLATFORMS) np = CLH_MAX_PLATFORMS;
  for (cl_uint p = 0; p < np; p++) {
    cl_device_id devs[CLH_MAX_DEVICES];
    cl_uint nd = 0;
    rc = clGetDeviceIDs(plats[p], CL_DEVICE_TYPE_ALL, CLH_MAX_DEVICES, devs, &nd);
    if (rc == CL_DEVICE_NOT_FOUND) continue; /* a platform without devices is not an error */
    if (rc != CL_SUCCESS)
      return bk_fail(err, BK_ERR_RUNTIME, "OpenCL: clGetDeviceIDs on platform %u failed: %s",
                     p, clh_error_name(rc));
    if (nd > CLH_MAX_DEVICES) nd = CLH_MAX_DEVICES;
    for (cl_uint d = 0; d < nd && *count < cap; d++) {
      clh_dev_entry_t *e = &list[(*count)++];
      memset(e, 0, sizeof *e);
      e->platform = plats[p];
      e->device = devs[d];
      e->pi = (int)p;
      e->di = (int)d;
      clGetPlatformInfo(plats[p], CL_PLATFORM_NAME, sizeof e->pname - 1, e->pname, NULL);
      clGetPlatformInfo(plats[p], CL_PLATFORM_VENDOR, sizeof e->pvendor - 1, e->pvendor, NULL);
      clGetDeviceInfo(devs[d], CL_DEVICE_NAME, sizeof e->dname - 1, e->dname, NULL);
      clGetDeviceInfo(devs[d], CL_DEVICE_TYPE, sizeof e->type, &e->type, NULL);
    }
  }
  if (*count == 0)
    return bk_fail(err, BK_ERR_RUNTIME,
                   "OpenCL platforms found but they have no devices; see `clinfo`");
  return BK_OK;
}

static int default_index(const clh_dev_entry_t *list, int n) {
  for (int i = 0; i < n; i++)
    if (is_pocl(&list[i])) return i;
  return 0;
}

static const char *type_name(cl_device_type t) {
  if (t & CL_DEVICE_TYPE_GPU) return "GPU";
  if (t & CL_DEVICE_TYPE_CPU) return "CPU";
  if (t & CL_DEVICE_TYPE_ACCELERATOR) return "accelerator";
  return "other";
}

/* One line per device: "  0:0  platform / device (CPU) [default]". */
static void format_list(const clh_dev_entry_t *list, int n, char *buf, size_t len) {
  size_t used = 0;
  int def = default_index(list, n);
  buf[0] = 0;
  for (int i = 0; i < n && used < len; i++) {
    int w = snprintf(buf + used, len - used, "  %d:%d  %s / %s (%s)%s\n", list[i].pi, list[i].di,
                     list[i].pname, list[i].dname, type_name(list[i].type),
                     i == def ? " [default]" : "");
    if (w < 0) break;
    used += (size_t)w;
  }
}

void clh_list_devices(FILE *out) {
  clh_dev_entry_t list[CLH_MAX_DEVICES];
  int n;
  bk_error_t err;
  if (clh_enumerate(list, CLH_MAX_DEVICES, &n, &err) != BK_OK) {
    fprintf(out, "%s\n", err.msg);
    return;
  }
  char buf[CLH_MAX_DEVICES * 300];
  format_list(list, n, buf, sizeof buf);
  fprintf(out, "OpenCL devices (choose with --device P:D or a name substring):\n%s", buf);
}

static int contains_nocase(const char *hay, const char *needle) {
  size_t hn = strlen(hay), nn = strlen(needle);
  if (nn == 0) return 1;
  for (size_t i = 0; i + nn <= hn; i++) {
    size_t k = 0;
    while (k < nn && tolower((unsigned char)hay[i + k]) == tolower((unsigned char)needle[k])) k++;
    if (k == nn) return 1;
  }
  return 0;
}

/* "P:D" indices, a device type, else a name substring; -1 when nothing matches. */
static int match_spec(const clh_dev_entry_t *list, int n, const char *spec) {
  int p, d, used = 0;
  if (sscanf(spec, "%d:%d%n", &p, &d, &used) == 2 && spec[used] == 0) {
    for (int i = 0; i < n; i++)
      if (list[i].pi == p && list[i].di == d) return i;
    return -1;
  }
  /* "gpu", "cpu", "accelerator": the first device of that kind */
  for (int i = 0; i < n; i++)
    if (strcasecmp(spec, type_name(list[i].type)) == 0) return i;
  for (int i = 0; i < n; i++)
    if (contains_nocase(list[i].dname, spec) || contains_nocase(list[i].pname, spec) ||
        contains_nocase(list[i].pvendor, spec))
      return i;
  return -1;
}

int clh_init(clh_context_t *cl, const char *device_spec, bk_error_t *err) {
  clh_dev_entry_t list[CLH_MAX_DEVICES];
  int n, rc;
  cl_int cerr = CL_SUCCESS;
  memset(cl, 0, sizeof *cl);
  rc = clh_enumerate(list, CLH_MAX_DEVICES, &n, err);
  if (rc != BK_OK) return rc;

  int pick = default_index(list, n);
  if (device_spec && device_spec[0]) {
    pick = match_spec(list, n, device_spec);
    if (pick < 0) {
      char buf[sizeof err->msg - 128];
      format_list(list, n, buf, sizeof buf);
      return bk_fail(err, BK_ERR_INPUT,
                     "--device '%s' matches no OpenCL device (expected P:D, gpu, cpu or part of a "
                     "platform/device name); available:\n%s",
                     device_spec, buf);
    }
  }
  const clh_dev_entry_t *e = &list[pick];
  cl->platform = e->platform;
  cl->device = e->device;
  snprintf(cl->platform_name, sizeof cl->platform_name, "%s", e->pname);
  snprintf(cl->device_name, sizeof cl->device_name, "%s", e->dname);
  /* BAKER_CL_DISCRETE=1: a CPU device's buffers handled as a GPU's (copies,
   * read-backs), so that PoCL tests the path a GPU takes */
  const char *discrete = getenv("BAKER_CL_DISCRETE");
  cl->is_cpu = (e->type & CL_DEVICE_TYPE_CPU) != 0 && !(discrete && strcmp(discrete, "1") == 0);
  cl_device_fp_config fp = 0;
  if (clGetDeviceInfo(cl->device, CL_DEVICE_SINGLE_FP_CONFIG, sizeof fp, &fp, NULL) == CL_SUCCESS)
    cl->exact_div_sqrt = (fp & CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT) != 0;

  char ext[8192] = {0};
  CLH_CHECK(clGetDeviceInfo(cl->device, CL_DRIVER_VERSION, sizeof cl->driver_version - 1,
                            cl->driver_version, NULL), err, error);
  CLH_CHECK(clGetDeviceInfo(cl->device, CL_DEVICE_MAX_COMPUTE_UNITS, sizeof cl->compute_units,
                            &cl->compute_units, NULL), err, error);
  CLH_CHECK(clGetDeviceInfo(cl->device, CL_DEVICE_GLOBAL_MEM_SIZE, sizeof cl->global_mem,
                            &cl->global_mem, NULL), err, error);
  CLH_CHECK(clGetDeviceInfo(cl->device, CL_DEVICE_MAX_MEM_ALLOC_SIZE, sizeof cl->max_alloc,
                            &cl->max_alloc, NULL), err, error);
  /* The extension list can be long; a truncated one would only hide int64 atomics. */
  size_t ext_len = 0;
  CLH_CHECK(clGetDeviceInfo(cl->device, CL_DEVICE_EXTENSIONS, 0, NULL, &ext_len), err, error);
  char *ext_heap = NULL;
  const char *exts = ext;
  if (ext_len >= sizeof ext) {
    ext_heap = calloc(ext_len + 1, 1);
    if (ext_heap) exts = ext_heap;
  }
  if (clGetDeviceInfo(cl->device, CL_DEVICE_EXTENSIONS, exts == ext ? sizeof ext - 1 : ext_len,
                      (void *)exts, NULL) == CL_SUCCESS)
    cl->has_int64_atomics = strstr(exts, "cl_khr_int64_base_atomics") != NULL;
  free(ext_heap);

  cl_context_properties props[] = {CL_CONTEXT_PLATFORM, (cl_context_properties)cl->platform, 0};
  cl->context = clCreateContext(props, 1, &cl->device, NULL, NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  cl->queue = clCreateCommandQueue(cl->context, cl->device, 0, &cerr);
  CLH_CHECK(cerr, err, error);

  char mem[32];
  bk_log(2, "OpenCL device %d:%d: %s / %s (%s, driver %s, %u compute units, %s, int64 atomics %s)",
         e->pi, e->di, cl->platform_name, cl->device_name, type_name(e->type), cl->driver_version,
         cl->compute_units, bk_format_bytes((double)cl->global_mem, mem, sizeof mem),
         cl->has_int64_atomics ? "yes" : "no");
  return BK_OK;

error:
  clh_release(cl);
  return err ? err->code : BK_ERR_RUNTIME;
}

void clh_release(clh_context_t *cl) {
  if (!cl) return;
  for (int i = 0; i < cl->kept_count; i++) clReleaseProgram(cl->kept[i].program);
  cl->kept_count = cl->kept_next = 0;
  for (int i = 0; i < 2; i++) {
    if (cl->stage_map[i])
      clEnqueueUnmapMemObject(cl->queue, cl->stage[i], cl->stage_map[i], 0, NULL, NULL);
    if (cl->stage[i]) clReleaseMemObject(cl->stage[i]);
    cl->stage[i] = NULL;
    cl->stage_map[i] = NULL;
  }
  if (cl->queue) clFinish(cl->queue);
  if (cl->queue) clReleaseCommandQueue(cl->queue);
  if (cl->context) clReleaseContext(cl->context);
  cl->queue = NULL;
  cl->context = NULL;
  cl->device = NULL;
  cl->platform = NULL;
}

/* --- binary cache ----------------------------------------------------------- */

/* File layout: magic, key, binary size, binary. The key in the file guards
 * against a renamed or foreign file; the size against truncation. */
static const char cache_magic[8] = {'B', 'K', 'C', 'L', 'B', 'I', 'N', '1'};

static unsigned char *cache_load(const char *path, uint64_t key, size_t *size) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  char magic[8];
  uint64_t k = 0, n = 0;
  unsigned char *bin = NULL;
  if (fread(magic, 1, 8, f) != 8 || memcmp(magic, cache_magic, 8) != 0 ||
      fread(&k, sizeof k, 1, f) != 1 || k != key || fread(&n, sizeof n, 1, f) != 1 || n == 0 ||
      n > ((uint64_t)1 << 31)) {
    bk_log(2, "kernel cache: %s is not a valid cache file, ignoring it", path);
    goto done;
  }
  bin = malloc((size_t)n);
  if (bin && fread(bin, 1, (size_t)n, f) != (size_t)n) {
    bk_log(2, "kernel cache: %s is truncated, ignoring it", path);
    free(bin);
    bin = NULL;
    goto done;
  }
  *size = (size_t)n;
done:
  fclose(f);
  return bin;
}

static void cache_store(const char *dir, const char *path, uint64_t key, cl_program prog) {
  size_t size = 0;
  unsigned char *bin = NULL;
  FILE *f = NULL;
  char tmp[4200];
  tmp[0] = 0;
  if (clGetProgramInfo(prog, CL_PROGRAM_BINARY_SIZES, sizeof size, &size, NULL) != CL_SUCCESS ||
      size == 0) {
    bk_log(2, "kernel cache: the driver gives no program binary; not caching");
    return;
  }
  bin = malloc(size);
  if (!bin) return;
  if (clGetProgramInfo(prog, CL_PROGRAM_BINARIES, sizeof bin, &bin, NULL) != CL_SUCCESS) {
    bk_log(2, "kernel cache: clGetProgramInfo(CL_PROGRAM_BINARIES) failed; not caching");
    goto done;
  }
  if (clh_mkdir_p(dir) != 0) {
    bk_log(2, "kernel cache: cannot create %s (%s); not caching", dir, strerror(errno));
    goto done;
  }
  bk_temp_path(path, tmp, sizeof tmp);
  f = fopen(tmp, "wb");
  uint64_t n = size;
  if (!f || fwrite(cache_magic, 1, 8, f) != 8 || fwrite(&key, sizeof key, 1, f) != 1 ||
      fwrite(&n, sizeof n, 1, f) != 1 || fwrite(bin, 1, size, f) != size) {
    bk_log(2, "kernel cache: cannot write %s (%s); not caching", tmp, strerror(errno));
    goto done;
  }
  int bad = fclose(f);
  f = NULL;
  if (bad != 0) {
    bk_log(2, "kernel cache: cannot write %s (%s); not caching", tmp, strerror(errno));
    goto done;
  }
  bk_error_t e;
  if (bk_commit_temp(tmp, path, &e) != BK_OK) {
    bk_log(2, "kernel cache: %s", e.msg);
    tmp[0] = 0; /* bk_commit_temp removed it */
    goto done;
  }
  tmp[0] = 0;
  bk_log(2, "kernel cache: stored %s (%zu bytes)", path, size);
done:
  if (f) fclose(f);
  if (tmp[0]) remove(tmp);
  free(bin);
}


/* --- program builds --------------------------------------------------------- */

static char *build_log(clh_context_t *cl, cl_program prog) {
  size_t n = 0;
  if (clGetProgramBuildInfo(prog, cl->device, CL_PROGRAM_BUILD_LOG, 0, NULL, &n) != CL_SUCCESS)
    return NULL;
  char *log = calloc(n + 1, 1);
  if (log && clGetProgramBuildInfo(prog, cl->device, CL_PROGRAM_BUILD_LOG, n, log, NULL) !=
                 CL_SUCCESS) {
    free(log);
    return NULL;
  }
  /* drop trailing blank lines, which PoCL leaves */
  while (log && n > 0 && (log[n - 1] == '\n' || log[n - 1] == ' ' || log[n - 1] == 0))
    log[--n] = 0;
  return log;
}

/* The key covers everything that changes the binary: the expanded source,
 * the options and the exact device and driver. */
static uint64_t clh_cache_key(const clh_context_t *cl, const char *src, const char *opts) {
  uint64_t key = BK_HASH_SEED;
  key = bk_hash64(src, strlen(src) + 1, key);
  key = bk_hash64(opts, strlen(opts) + 1, key);
  key = bk_hash64(cl->device_name, strlen(cl->device_name) + 1, key);
  key = bk_hash64(cl->driver_version, strlen(cl->driver_version) + 1, key);
  key = bk_hash64(cl->platform_name, strlen(cl->platform_name) + 1, key);
  return key;
}

/* The program from the cache entry at `path`, or NULL when there is none or
 * the driver rejects it (a driver update can do that): the caller then
 * builds from source and stores it again. Counts the hit or the miss. */
static cl_program clh_load_cached(clh_context_t *cl, const char *name, const char *path,
                                  uint64_t key, const char *opts, double t0) {
  size_t size = 0;
  unsigned char *bin = cache_load(path, key, &size);
  if (bin) {
    const unsigned char *bp = bin;
    cl_int status = CL_SUCCESS, cerr = CL_SUCCESS;
    cl_program prog =
        clCreateProgramWithBinary(cl->context, 1, &cl->device, &size, &bp, &status, &cerr);
    if (cerr == CL_SUCCESS && status == CL_SUCCESS &&
        clBuildProgram(prog, 1, &cl->device, opts, NULL, NULL) == CL_SUCCESS) {
      cl->stats.cache_hits++;
      cl->stats.last_hit = 1;
      cl->stats.last_ms = bk_now_ms() - t0;
      clc_touch(path); /* its mtime is its last use: pruning goes oldest first */
      bk_log(2, "%s: kernel cache hit %016llx (%.1f ms)", name, (unsigned long long)key,
             cl->stats.last_ms);
      free(bin);
      return prog;
    }
    bk_log(2, "kernel cache: %s was rejected by the driver (%s); rebuilding", path,
           clh_error_name(cerr != CL_SUCCESS ? cerr : status));
    if (prog) clReleaseProgram(prog);
    free(bin);
  }
  cl->stats.cache_misses++;
  bk_log(2, "%s: kernel cache miss %016llx", name, (unsigned long long)key);
  return NULL;
}

/* A failed build's message with its log. The first errors are the useful
 * ones, so a log too long for err->msg is cut there and printed whole to
 * stderr. */
static void clh_build_failed(const clh_context_t *cl, const char *name, const char *opts,
                             cl_int cerr, const char *log, bk_error_t *err) {
  const char *lg = log && log[0] ? log : "(the driver gave no build log)";
  size_t room = sizeof err->msg - CLH_LOG_RESERVE - strlen(name) - strlen(opts);
  size_t ll = strlen(lg);
  if (room > sizeof err->msg) room = 0; /* very long names or options */
  if (ll > room) {
    fprintf(stderr, "full OpenCL build log of %s:\n%s\n", name, lg);
    bk_fail(err, BK_ERR_RUNTIME,
            "%s: OpenCL build failed (%s) on %s with options '%s'; build log:\n%.*s\n"
            "[... %zu more bytes of build log, printed in full above]",
            name, clh_error_name(cerr), cl->device_name, opts, (int)room, lg, ll - room);
  } else {
    bk_fail(err, BK_ERR_RUNTIME,
            "%s: OpenCL build failed (%s) on %s with options '%s'; build log:\n%s", name,
            clh_error_name(cerr), cl->device_name, opts, lg);
  }
}

/* Compiles the expanded source; the build log is printed when verbose, and
 * is the error message when the build fails. */
static int clh_compile(clh_context_t *cl, const char *name, const char *src, const char *opts,
                       double t0, cl_program *out, bk_error_t *err) {
  char *log = NULL;
  cl_program prog = NULL;
  cl_int cerr = CL_SUCCESS;
  int rc = BK_ERR_RUNTIME;
  const char *sp = src;
  prog = clCreateProgramWithSource(cl->context, 1, &sp, NULL, &cerr);
  CLH_CHECK(cerr, err, error);
  cerr = clBuildProgram(prog, 1, &cl->device, opts, NULL, NULL);
  log = build_log(cl, prog);
  if (cerr != CL_SUCCESS) {
    clh_build_failed(cl, name, opts, cerr, log, err);
    goto error;
  }
  cl->stats.source_builds++;
  cl->stats.last_ms = bk_now_ms() - t0;
  bk_log(2, "%s: built from source in %.1f ms (options '%s')", name, cl->stats.last_ms, opts);
  if (log && log[0]) bk_log(2, "build log of %s:\n%s", name, log);
  *out = prog;
  prog = NULL;
  rc = BK_OK;

error:
  if (prog) clReleaseProgram(prog);
  free(log);
  return rc;
}

/* A program this context built before under `key`, with a reference for
 * the caller; NULL when none. */
static cl_program kept_program(clh_context_t *cl, uint64_t key) {
  for (int i = 0; i < cl->kept_count; i++)
    if (cl->kept[i].key == key && clRetainProgram(cl->kept[i].program) == CL_SUCCESS) {
      cl->stats.kept_hits++;
      cl->stats.last_hit = 2;
      cl->stats.last_ms = 0.0;
      bk_log(2, "kernel %016llx: built before in this run, reused", (unsigned long long)key);
      return cl->kept[i].program;
    }
  return NULL;
}

/* Keeps a reference to a built program (the oldest one out when full). */
static void keep_program(clh_context_t *cl, uint64_t key, cl_program program) {
  if (!cl->keep_programs || clRetainProgram(program) != CL_SUCCESS) return;
  int slot = cl->kept_count;
  if (cl->kept_count < CLH_KEPT_PROGRAMS) {
    cl->kept_count++;
  } else {
    slot = cl->kept_next;
    cl->kept_next = (slot + 1) % CLH_KEPT_PROGRAMS;
    clReleaseProgram(cl->kept[slot].program);
  }
  cl->kept[slot].key = key;
  cl->kept[slot].program = program;
}

int clh_build_source(clh_context_t *cl, const char *name, const char *text, const char *options,
                     cl_program *out, bk_error_t *err) {
  char *src = NULL, *opts = NULL;
  int rc = BK_ERR_RUNTIME;
  char dir[4096], path[4200];
  *out = NULL;
  if (!options) options = "";

  src = clh_expand_with(clh_embedded_sources, name, text, err);
  if (!src) goto error;
  size_t olen = strlen(options) + 80;
  opts = malloc(olen);
  if (!opts) {
    bk_fail(err, BK_ERR_RUNTIME, "%s: out of memory", name);
    goto error;
  }
  /* IEEE division and square root where the device offers them (a GPU's
   * default is within 2.5-3 ulp): with the kernels' own exp, log, sin and
   * cos (kernels/shared.h) every device then bakes the same bits (docs/gpu.md). */
  snprintf(opts, olen, "-cl-std=CL1.2%s %s",
           cl->exact_div_sqrt ? " -cl-fp32-correctly-rounded-divide-sqrt" : "", options);

  uint64_t key = clh_cache_key(cl, src, opts);
  cl->stats.last_key = key;
  cl->stats.last_hit = 0;
  if ((*out = kept_program(cl, key)) != NULL) {
    rc = BK_OK;
    goto error; /* the cleanup block */
  }
  int use_cache = clh_cache_dir(dir, sizeof dir);
  if (use_cache) snprintf(path, sizeof path, "%s/%016llx.clbin", dir, (unsigned long long)key);
  double t0 = bk_now_ms();

  if (use_cache && (*out = clh_load_cached(cl, name, path, key, opts, t0)) != NULL) {
    keep_program(cl, key, *out);
    rc = BK_OK;
    goto error; /* the cleanup block */
  }
  rc = clh_compile(cl, name, src, opts, t0, out, err);
  if (rc == BK_OK && use_cache) {
    cache_store(dir, path, key, *out);
    clc_prune(dir, clc_max_bytes(), path); /* the cap, least recently used first */
  }
  if (rc == BK_OK) keep_program(cl, key, *out);

error:
  free(src);
  free(opts);
  return rc;
}

int clh_build(clh_context_t *cl, const char *file, const char *options, cl_program *out,
              bk_error_t *err) {
  const clh_source_t *s = clh_find_source(clh_embedded_sources, file);
  *out = NULL;
  if (!s)
    return bk_fail(err, BK_ERR_RUNTIME,
                   "kernels/%s: not among the embedded kernel files (add it to kernels/ and "
                   "re-run cmake)", file);
  char name[300];
  snprintf(name, sizeof name, "kernels/%s", s->name);
  return clh_build_source(cl, name, s->text, options, out, err);
}
