/* clcopy.c: large host-device copies through pinned staging (clcopy.h). */
#include "clcopy.h"

#include <string.h>

#include "../base/parallel.h"

/* The context's two staging buffers, made and mapped on first use. */
static int stage_open(clh_context_t *cl, bk_error_t *err) {
  cl_int cerr = CL_SUCCESS;
  for (int i = 0; i < 2 && !cl->stage_map[i]; i++) {
    cl->stage[i] = clCreateBuffer(cl->context, CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, CLC_STAGE,
                                  NULL, &cerr);
    CLH_CHECK(cerr, err, error);
    cl->stage_map[i] = clEnqueueMapBuffer(cl->queue, cl->stage[i], CL_TRUE,
                                          CL_MAP_READ | CL_MAP_WRITE, 0, CLC_STAGE, 0, NULL, NULL,
                                          &cerr);
    CLH_CHECK(cerr, err, error);
  }
  return BK_OK;
error:
  return BK_ERR_RUNTIME;
}

typedef struct copy_job {
  char *to;
  const char *from;
} copy_job_t;

static void copy_range(void *ctx, size_t lo, size_t hi) {
  const copy_job_t *j = ctx;
  memcpy(j->to + lo, j->from + lo, hi - lo);
}

/* memcpy on all cores: one core's copy into pageable memory is slower than
 * the bus */
static void copy_parallel(void *to, const void *from, size_t n) {
  copy_job_t j = {to, from};
  bk_parallel(n, (size_t)1 << 20, copy_range, &j);
}

static int wait_release(cl_event *e, bk_error_t *err) {
  if (!*e) return BK_OK;
  cl_int rc = clWaitForEvents(1, e);
  clReleaseEvent(*e);
  *e = NULL;
  CLH_CHECK(rc, err, error);
  return BK_OK;
error:
  return BK_ERR_RUNTIME;
}

static int direct(const clh_context_t *cl, size_t bytes) {
  return cl->is_cpu || bytes <= 2 * CLC_STAGE;
}

int clc_read(clh_context_t *cl, cl_mem b, size_t bytes, void *host, bk_error_t *err) {
  if (direct(cl, bytes)) {
    CLH_CHECK(clEnqueueReadBuffer(cl->queue, b, CL_TRUE, 0, bytes, host, 0, NULL, NULL), err,
              error);
    return BK_OK;
  }
  if (stage_open(cl, err)) return BK_ERR_RUNTIME;
  cl_event ev[2] = {NULL, NULL};
  size_t prev = 0, prev_n = 0;
  int rc = BK_ERR_RUNTIME;
  /* chunk i lands in stage i % 2 while the host copies out chunk i - 1 */
  for (size_t off = 0, i = 0; off < bytes; off += CLC_STAGE, i++) {
    const int k = (int)(i & 1);
    const size_t n = bytes - off < CLC_STAGE ? bytes - off : CLC_STAGE;
    CLH_CHECK(
        clEnqueueReadBuffer(cl->queue, b, CL_FALSE, off, n, cl->stage_map[k], 0, NULL, &ev[k]), err,
        done);
    if (i > 0) {
      if (wait_release(&ev[1 - k], err)) goto done;
      copy_parallel((char *)host + prev, cl->stage_map[1 - k], prev_n);
    }
    prev = off;
    prev_n = n;
  }
  const int last = (int)(((bytes + CLC_STAGE - 1) / CLC_STAGE - 1) & 1);
  if (wait_release(&ev[last], err)) goto done;
  copy_parallel((char *)host + prev, cl->stage_map[last], prev_n);
  rc = BK_OK;
done:
  for (int k = 0; k < 2; k++) wait_release(&ev[k], err);
  return rc;
error:
  return BK_ERR_RUNTIME;
}

int clc_write(clh_context_t *cl, cl_mem b, size_t bytes, const void *host, bk_error_t *err) {
  if (direct(cl, bytes)) {
    CLH_CHECK(clEnqueueWriteBuffer(cl->queue, b, CL_TRUE, 0, bytes, host, 0, NULL, NULL), err,
              error);
    return BK_OK;
  }
  if (stage_open(cl, err)) return BK_ERR_RUNTIME;
  cl_event ev[2] = {NULL, NULL};
  int rc = BK_ERR_RUNTIME;
  /* the host fills stage i % 2 once the device has taken chunk i - 2 from it */
  for (size_t off = 0, i = 0; off < bytes; off += CLC_STAGE, i++) {
    const int k = (int)(i & 1);
    const size_t n = bytes - off < CLC_STAGE ? bytes - off : CLC_STAGE;
    if (wait_release(&ev[k], err)) goto done;
    copy_parallel(cl->stage_map[k], (const char *)host + off, n);
    CLH_CHECK(
        clEnqueueWriteBuffer(cl->queue, b, CL_FALSE, off, n, cl->stage_map[k], 0, NULL, &ev[k]),
        err, done);
  }
  rc = BK_OK;
done:
  for (int k = 0; k < 2; k++)
    if (wait_release(&ev[k], err)) rc = BK_ERR_RUNTIME;
  return rc;
error:
  return BK_ERR_RUNTIME;
}

#define CLC_ZERO_CHUNKS 64

typedef struct zero_job {
  const unsigned char *p;
  unsigned char found[CLC_ZERO_CHUNKS]; /* chunk k holds a nonzero byte */
} zero_job_t;

static void zero_chunk(void *ctx, size_t k, size_t lo, size_t hi) {
  zero_job_t *j = ctx;
  unsigned char any = 0;
  for (size_t i = lo; i < hi; i++) any |= j->p[i];
  j->found[k] = any != 0;
}

int clc_upload(clh_context_t *cl, cl_mem b, size_t bytes, const void *host, bk_error_t *err) {
  zero_job_t z = {host, {0}};
  bk_parallel_chunks(bytes, CLC_ZERO_CHUNKS, zero_chunk, &z);
  for (int k = 0; k < CLC_ZERO_CHUNKS; k++)
    if (z.found[k]) return clc_write(cl, b, bytes, host, err);
  const uint64_t zero = 0;
  const size_t pattern = bytes % sizeof zero ? 1 : sizeof zero;
  CLH_CHECK(clEnqueueFillBuffer(cl->queue, b, &zero, pattern, 0, bytes, 0, NULL, NULL), err, error);
  return BK_OK;
error:
  return BK_ERR_RUNTIME;
}
