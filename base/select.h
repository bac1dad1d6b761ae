/* select.h: the value of a given rank among floats (an order statistic),
 * for the percentiles of the error's lit-voxel threshold and of the
 * adaptive pipeline's automatic thresholds. */
#ifndef BAKER_SELECT_H
#define BAKER_SELECT_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The value of 0-based rank `rank` (ascending) among v[0..n), rank < n, v
 * left as it is; NaN when n is 0 or memory runs out. v holds no NaN. */
float bk_rank_value(const float *v, size_t n, size_t rank);

/* The lower nearest rank of quantile q in [0, 1]: rank floor(q (n - 1)). */
float bk_quantile(const float *v, size_t n, double q);

#ifdef __cplusplus
}
#endif

#endif
