/* frame_reuse.c: the state a batch of frames keeps (see frame_reuse.h). */
#include "frame_reuse.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/common.h"
#include "budget.h"
#include "clenv.h"

static void mix(uint64_t *h, const void *data, size_t len) { *h = bk_hash64(data, len, *h); }
static void mix_string(uint64_t *h, const char *s) { mix(h, s, strlen(s) + 1); }

/* Eight bytes per multiply (bk_hash64 takes one): a baked 256^3 file is
 * hundreds of MB, and hashing it must cost little beside reading it. */
static void mix_words(uint64_t *h, const unsigned char *p, size_t n) {
  uint64_t x = *h, w;
  size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    memcpy(&w, p + i, 8);
    x = (x ^ w) * 0x9E3779B97F4A7C15ull;
    x ^= x >> 29;
  }
  *h = bk_hash64(p + i, n - i, x);
}

uint64_t fr_file_key(const char *path) {
  enum { CHUNK = 1 << 20 };
  uint64_t h = BK_HASH_SEED;
  /* a pipe or a device is not read here (its reader would then find the
   * pipe empty, or /dev/zero never end): a key no other call gives */
  const bk_file_kind_t kind = bk_file_kind(path);
  if (kind == BK_FILE_PIPE || kind == BK_FILE_OTHER) {
    static _Atomic uint64_t unique;
    const uint64_t n = ++unique;
    mix(&h, &n, sizeof n);
    return h ? h : 1;
  }
  FILE *f = fopen(path, "rb");
  unsigned char *buf = f ? malloc(CHUNK) : NULL;
  if (!buf) {
    int e = f ? ENOMEM : errno;
    mix(&h, &e, sizeof e);
    if (f) fclose(f);
    return h ? h : 1;
  }
  size_t n;
  while ((n = fread(buf, 1, CHUNK, f)) > 0) mix_words(&h, buf, n);
  free(buf);
  int bad = ferror(f);
  mix(&h, &bad, sizeof bad);
  fclose(f);
  return h ? h : 1;
}

/* A file by its path and contents (a mesh sequence whose frames hold the
 * same mesh is still the same input). */
static void mix_file(uint64_t *h, const char *path) {
  mix_string(h, path);
  uint64_t k = fr_file_key(path);
  mix(h, &k, sizeof k);
}

static void mix_vdb(uint64_t *h, const scene_vdb_ref_t *r) {
  mix(h, &r->present, sizeof r->present);
  if (!r->present) return;
  mix_file(h, r->file);
  mix_string(h, r->grid);
}

uint64_t fr_volume_key(const scene_t *s) {
  uint64_t h = BK_HASH_SEED;
  mix(&h, s->bounds_min, sizeof s->bounds_min);
  mix(&h, s->bounds_max, sizeof s->bounds_max);
  mix(&h, &s->resolution, sizeof s->resolution);
  mix(&h, &s->ior_smoothing, sizeof s->ior_smoothing);
  mix(&h, &s->crop_to_objects, sizeof s->crop_to_objects);
  mix(&h, s->medium_sigma_s, sizeof s->medium_sigma_s);
  mix(&h, s->medium_sigma_a, sizeof s->medium_sigma_a);
  mix(&h, &s->medium_ior, sizeof s->medium_ior);
  mix(&h, &s->medium_g, sizeof s->medium_g);
  mix_vdb(&h, &s->density_vdb);
  mix_vdb(&h, &s->ior_vdb);
  mix(&h, &s->object_count, sizeof s->object_count);
  for (int i = 0; i < s->object_count; i++) {
    const scene_object_t *o = &s->objects[i];
    mix_file(&h, o->mesh);
    mix(&h, &o->ior, sizeof o->ior);
    mix(&h, o->ior_rgb, sizeof o->ior_rgb);
    mix(&h, o->sigma_a, sizeof o->sigma_a);
    mix(&h, o->sigma_s, sizeof o->sigma_s);
    mix(&h, &o->g, sizeof o->g);
    mix(&h, o->scale, sizeof o->scale);
    mix(&h, o->rotate_deg, sizeof o->rotate_deg);
    mix(&h, o->translate, sizeof o->translate);
  }
  return h ? h : 1;
}

static uint64_t cl_key_of(const char *device) {
  uint64_t key = BK_HASH_SEED;
  mix_string(&key, device ? device : "");
  return key;
}

/* The driver may give the thread a signal stack of its own (PoCL's start-up
 * does, from malloc); the thread's own is put back before it ends, since the
 * thread's exit frees the one it set up (AddressSanitizer's aborts on a
 * stack it did not map). */
static void *open_cl_thread(void *arg) {
  bake_reuse_t *r = arg;
  const double t0 = bk_now_ms();
  stack_t own, now;
  const int saved = sigaltstack(NULL, &own) == 0;
  r->cl_rc = clh_init(&r->cl, r->cl_device, &r->cl_err);
  if (saved && sigaltstack(NULL, &now) == 0 && now.ss_sp != own.ss_sp) sigaltstack(&own, NULL);
  r->cl_ms = bk_now_ms() - t0;
  return NULL;
}

/* Starts opening the context for `device` unless it is kept already; if no
 * thread can be made, fr_opencl opens it as before. */
static void fr_opencl_begin(bake_reuse_t *r, const char *device, int frame) {
  const uint64_t key = cl_key_of(device);
  if (r->cl_opening || (r->has_cl && r->cl_key == key)) return;
  fr_drop_opencl(r);
  clh_prepare_env(); /* setenv here, not beside this thread's getenv calls */
  r->cl_device = device;
  r->cl_key = key;
  r->cl_frame = frame;
  r->cl_opening = pthread_create(&r->cl_thread, NULL, open_cl_thread, r) == 0;
}

/* Joins the opening thread: 1 when it opened the context (now kept), -1
 * when it failed (r->cl_err says why), 0 when none was opening. */
static int fr_opencl_join(bake_reuse_t *r) {
  if (!r->cl_opening) return 0;
  pthread_join(r->cl_thread, NULL);
  r->cl_opening = 0;
  if (r->cl_rc) {
    clh_release(&r->cl);
    memset(&r->cl, 0, sizeof r->cl);
    return -1;
  }
  r->cl.keep_programs = 1; /* the next frames build the same kernels */
  r->has_cl = 1;
  return 1;
}

/* A grid whose sums the device cannot hold in one buffer is refused before
 * its voxels are made: for sums over BUDGET_DEVICE_CHECK_BYTES the context
 * is waited for (opened now where the voxelizer's VDB reader kept it from
 * starting: nothing forks while it loads, as it is joined at once). */
static int fr_device_check(bake_reuse_t *r, const scene_t *s, const float (*box)[3],
                           const char *device, bk_error_t *err) {
  if (budget_sums_bytes(s, box) <= BUDGET_DEVICE_CHECK_BYTES) return BK_OK;
  const double t0 = bk_now_ms();
  fr_opencl_begin(r, device, s->frame); /* nothing when it is opening or kept */
  const int joined = fr_opencl_join(r);
  if (joined < 0) {
    *err = r->cl_err;
    return err->code;
  }
  r->cl_unreported = joined;
  r->cl_waited_ms = bk_now_ms() - t0;
  if (!r->has_cl) return BK_OK;
  return budget_device_check(s, box, r->cl.max_alloc, r->cl.device_name, err);
}

void fr_opencl_settle(bake_reuse_t *r) { (void)fr_opencl_join(r); }

int fr_volume(bake_reuse_t *r, const scene_t *s, uint64_t max_memory, const char *cl_device,
              bk_timings_t *t, bk_error_t *err) {
  double t0 = bk_now_ms();
  uint64_t key = fr_volume_key(s);
  r->cl_unreported = 0; /* a context from an earlier frame is reported as reused */
  if (r->has_volume && r->volume.key == key) {
    bk_timings_add(t, "voxelize", bk_now_ms() - t0, "reused from frame %d (inputs unchanged)",
                   r->volume_frame);
    bk_timings_mark_reused(t, r->volume_frame);
    return BK_OK;
  }
  /* before the budget: it counts this machine's free memory */
  vox_free(&r->volume);
  pm_field_cache_free(&r->fields);
  r->has_volume = 0;
  /* the whole bake's peak, before anything the size of the grid exists (a
   * kept volume passed it with the same grid) */
  /* dispersion keeps a {∇n, n} field per channel: 32 B more */
  double kept = FR_KEPT_FIELDS_BYTES + (scene_has_dispersion(s) ? 46.0 : 0.0);
  /* a vacuum's crop needs the objects' box before the budget: the meshes
   * are read once, for the box and for the voxels */
  vox_meshes_t meshes = {0};
  const int crops = scene_crops(s);
  int rc = crops ? vox_meshes_load(s, &meshes, err) : BK_OK;
  const float(*box)[3] = crops ? (const float(*)[3])meshes.box : NULL;
  int code_grey = 0;
  if (!rc)
    rc = budget_check(s, box, max_memory, (r->keep_fields ? kept : 0.0) + r->extra_bytes,
                      &code_grey, err);
  bk_error_t without;
  if (rc == BK_ERR_INPUT && r->keep_fields &&
      budget_check(s, box, max_memory, r->extra_bytes, &code_grey, &without) == BK_OK) {
    /* an optimisation, not worth a refusal: each frame builds its own */
    bk_warn("%s: the march's fields are not kept from frame to frame: they would add %.0f "
            "bytes per voxel to a peak that then does not fit (%s)",
            s->path, kept, err->msg);
    r->keep_fields = 0;
    rc = BK_OK;
  }
  /* the meshes before the context's thread starts: each is read in a
   * forked child, and a fork while another thread loads libraries is not
   * safe (the VDB readers keep it from starting for the same reason) */
  if (!rc && !crops) rc = vox_meshes_load(s, &meshes, err); /* the budget needed none */
  if (!rc && cl_device && !s->density_vdb.present && !s->ior_vdb.present)
    fr_opencl_begin(r, cl_device, s->frame);
  if (!rc && cl_device) rc = fr_device_check(r, s, box, cl_device, err);
  if (!rc) rc = vox_build_meshes(s, &meshes, code_grey, &r->volume, t, err);
  vox_meshes_free(&meshes);
  if (rc) return rc;
  r->volume.key = key;
  r->has_volume = 1;
  r->volume_frame = s->frame;
  return BK_OK;
}

int fr_opencl(bake_reuse_t *r, const char *device, int frame, bk_timings_t *t, bk_error_t *err) {
  const uint64_t key = cl_key_of(device);
  double t0 = bk_now_ms();
  const int early = fr_opencl_join(r);
  if (early < 0) {
    *err = r->cl_err;
    return err->code;
  }
  if ((early || r->cl_unreported) && r->cl_key == key) {
    if (r->cl_unreported)
      bk_timings_add(t, "OpenCL init", r->cl_waited_ms, "%s, opened before the voxels were made, "
                     "for its buffer limit (%.0f ms on its own thread)", r->cl.device_name,
                     r->cl_ms);
    else
      bk_timings_add(t, "OpenCL init", bk_now_ms() - t0, "%s, opened while the voxels were "
                     "made (%.0f ms on its own thread)", r->cl.device_name, r->cl_ms);
    r->cl_unreported = 0;
    return BK_OK;
  }
  if (r->has_cl && r->cl_key == key) {
    bk_timings_add(t, "OpenCL init", 0.0, "reused from frame %d (device unchanged), %d kernels",
                   r->cl_frame, r->cl.kept_count);
    bk_timings_mark_reused(t, r->cl_frame);
    return BK_OK;
  }
  fr_drop_opencl(r);
  t0 = bk_now_ms();
  int rc = clh_init(&r->cl, device, err);
  if (rc) {
    clh_release(&r->cl);
    memset(&r->cl, 0, sizeof r->cl);
    return rc;
  }
  r->cl.keep_programs = 1; /* the next frames build the same kernels */
  r->has_cl = 1;
  r->cl_key = key;
  r->cl_frame = frame;
  bk_timings_add(t, "OpenCL init", bk_now_ms() - t0, "%s", r->cl.device_name);
  return BK_OK;
}

void fr_drop_opencl(bake_reuse_t *r) {
  fr_opencl_join(r);
  if (r->has_cl) clh_release(&r->cl);
  memset(&r->cl, 0, sizeof r->cl);
  r->has_cl = r->cl_unreported = 0;
}

void fr_free(bake_reuse_t *r) {
  if (!r) return;
  fr_drop_opencl(r);
  pm_field_cache_free(&r->fields);
  vox_free(&r->volume);
  memset(r, 0, sizeof *r);
}
