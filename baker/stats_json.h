/* stats_json.h: `--stats PATH.json`, one bake frame as JSON for pipelines
 * and farms: every stage's time, the photon counts, the peak memory and the
 * error terms (docs/error.md). Written to a temporary name and renamed. */
#ifndef BAKER_STATS_JSON_H
#define BAKER_STATS_JSON_H

#include "base/common.h"
#include "batches.h"
#include "march.h"
#include "scene.h"

typedef struct sj_frame {
  const char *scene_path, *out_path;
  int frame;
  const scene_t *scene;
  const bk_timings_t *timings;
  const pm_stats_t *stats;
  const bt_result_t *error; /* the batches and the error terms; NULL: not measured */
} sj_frame_t;

/* Peak resident memory of this process so far, bytes (0 when unknown). */
uint64_t sj_peak_rss(void);
/* Writes f to path (a frame pattern already expanded). */
int sj_write(const char *path, const sj_frame_t *f, bk_error_t *err);

#endif
