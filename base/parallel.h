/* parallel.h: the one thread fan-out of the project, for loops over voxels
 * and slices around the OpenCL stages (radiance conversion, the adaptive
 * filter on the host).
 *
 * bk_parallel runs fn(ctx, lo, hi) over [0, n) split into one contiguous
 * range per CPU core, each at least `grain` items (BK_GRAIN for voxels),
 * and returns when all are done. A thread that cannot start leaves its range
 * to the caller's thread, so the loop always completes. */
#ifndef BAKER_PARALLEL_H
#define BAKER_PARALLEL_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#define BK_GRAIN 65536
/* --threads N: at most n threads in bk_parallel (0: one per core), and the
 * same cap for PoCL's CPU device (POCL_MAX_PTHREAD_COUNT, which PoCL 3 reads
 * when its platform is created, and POCL_CPU_MAX_CU_COUNT, its name since
 * PoCL 4): call before any OpenCL use. */
void bk_set_threads(int n);
void bk_parallel(size_t n, size_t grain, void (*fn)(void *ctx, size_t lo, size_t hi), void *ctx);
/* fn(ctx, k, lo, hi) for each chunk k of `chunks` fixed chunks of [0, n)
 * (chunk k is [n k / chunks, n (k+1) / chunks)), chunks side by side: for
 * reductions whose chunk results are combined in chunk order afterwards,
 * the same on every run and thread count. */
void bk_parallel_chunks(size_t n, int chunks, void (*fn)(void *ctx, size_t k, size_t lo, size_t hi),
                        void *ctx);

#ifdef __cplusplus
}
#endif
#endif
