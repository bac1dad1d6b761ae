/* parallel.c: one range of a loop per core (see parallel.h). */
#define _DEFAULT_SOURCE /* sysconf, setenv */
#include "parallel.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#define BK_MAX_THREADS 64

typedef struct bk_range_job {
  void (*fn)(void *ctx, size_t lo, size_t hi);
  void *ctx;
  size_t lo, hi;
} bk_range_job_t;

static int thread_limit; /* 0: one per core */

void bk_set_threads(int n) {
  char v[16];
  thread_limit = n > 0 ? n : 0;
  if (n <= 0) return;
  snprintf(v, sizeof v, "%d", n);
  setenv("POCL_MAX_PTHREAD_COUNT", v, 1);
  setenv("POCL_CPU_MAX_CU_COUNT", v, 1);
}

static void *range_run(void *arg) {
  bk_range_job_t *j = arg;
  j->fn(j->ctx, j->lo, j->hi);
  return NULL;
}

void bk_parallel(size_t n, size_t grain, void (*fn)(void *ctx, size_t lo, size_t hi), void *ctx) {
  long cpus = sysconf(_SC_NPROCESSORS_ONLN);
  if (thread_limit > 0 && cpus > thread_limit) cpus = thread_limit;
  int threads = cpus < 1 ? 1 : cpus > BK_MAX_THREADS ? BK_MAX_THREADS : (int)cpus;
  if (grain < 1) grain = 1;
  if ((size_t)threads > n / grain) threads = n / grain > 0 ? (int)(n / grain) : 1;
  bk_range_job_t jobs[BK_MAX_THREADS];
  pthread_t tid[BK_MAX_THREADS];
  int started = 0;
  for (int t = 0; t < threads; t++) {
    jobs[t].fn = fn;
    jobs[t].ctx = ctx;
    jobs[t].lo = n * (size_t)t / (size_t)threads;
    jobs[t].hi = n * (size_t)(t + 1) / (size_t)threads;
  }
  /* a thread that cannot start leaves its range to this one */
  for (int t = 1; t < threads; t++) {
    if (pthread_create(&tid[t], NULL, range_run, &jobs[t]) != 0) break;
    started = t;
  }
  range_run(&jobs[0]);
  for (int t = 1; t <= started; t++) pthread_join(tid[t], NULL);
  for (int t = started + 1; t < threads; t++) range_run(&jobs[t]);
}

typedef struct bk_chunk_job {
  size_t n;
  int chunks;
  void (*fn)(void *ctx, size_t k, size_t lo, size_t hi);
  void *ctx;
} bk_chunk_job_t;

static void chunk_range(void *arg, size_t k0, size_t k1) {
  const bk_chunk_job_t *j = arg;
  for (size_t k = k0; k < k1; k++)
    j->fn(j->ctx, k, j->n * k / (size_t)j->chunks, j->n * (k + 1) / (size_t)j->chunks);
}

void bk_parallel_chunks(size_t n, int chunks, void (*fn)(void *ctx, size_t k, size_t lo, size_t hi),
                        void *ctx) {
  bk_chunk_job_t j = {n, chunks, fn, ctx};
  bk_parallel((size_t)chunks, 1, chunk_range, &j);
}
