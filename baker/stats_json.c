/* stats_json.c: the --stats JSON of a bake frame (see stats_json.h). */
#include "stats_json.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>

uint64_t sj_peak_rss(void) {
  struct rusage ru;
  if (getrusage(RUSAGE_SELF, &ru) != 0) return 0;
  return (uint64_t)ru.ru_maxrss * 1024u; /* Linux: kilobytes */
}

/* A JSON string: quotes, backslashes and control characters escaped. */
static void put_string(FILE *f, const char *s) {
  fputc('"', f);
  for (; s && *s; s++) {
    unsigned char c = (unsigned char)*s;
    if (c == '"' || c == '\\') fprintf(f, "\\%c", c);
    else if (c < 32) fprintf(f, "\\u%04x", c);
    else fputc(c, f);
  }
  fputc('"', f);
}

/* A term, or null when not measured (JSON has no NaN). */
static void put_term(FILE *f, const char *key, double v, int last) {
  if (v >= 0.0 && isfinite(v)) fprintf(f, "    \"%s\": %.6g%s\n", key, v, last ? "" : ",");
  else fprintf(f, "    \"%s\": null%s\n", key, last ? "" : ",");
}

static void put_stages(FILE *f, const bk_timings_t *t) {
  double total = 0.0;
  fprintf(f, "  \"stages\": [\n");
  for (int i = 0; i < t->count; i++) {
    fprintf(f, "    {\"name\": ");
    put_string(f, t->stages[i].name);
    fprintf(f, ", \"ms\": %.3f, \"note\": ", t->stages[i].ms);
    put_string(f, t->stages[i].note);
    /* a batch of frames kept this stage's result from an earlier frame */
    if (t->stages[i].reused)
      fprintf(f, ", \"reused\": true, \"reused_from_frame\": %d", t->stages[i].reused_frame);
    else
      fprintf(f, ", \"reused\": false");
    fprintf(f, "}%s\n", i + 1 < t->count ? "," : "");
    total += t->stages[i].ms;
  }
  fprintf(f, "  ],\n  \"total_ms\": %.3f,\n", total);
}

static void put_photons(FILE *f, const sj_frame_t *x) {
  const pm_stats_t *s = x->stats;
  const bt_result_t *e = x->error;
  fprintf(f,
          "  \"photons\": {\n    \"traced\": %llu,\n    \"missed_grid\": %llu,\n"
          "    \"left_grid\": %llu,\n    \"absorbed\": %llu,\n    \"step_limit\": %llu,\n"
          "    \"steps\": %llu,\n    \"batches\": %d,\n    \"batch_photons\": %llu,\n"
          "    \"twin_photons\": %llu\n  },\n",
          (unsigned long long)s->photons, (unsigned long long)s->missed_grid,
          (unsigned long long)s->left_grid, (unsigned long long)s->absorbed,
          (unsigned long long)s->step_limit, (unsigned long long)s->steps, e ? e->batches : 0,
          (unsigned long long)(e ? e->batch_photons : 0),
          (unsigned long long)(e ? e->terms.twin_photons * (uint64_t)e->terms.twin_batches : 0));
}

static void put_all(FILE *f, const sj_frame_t *x) {
  const scene_t *s = x->scene;
  fprintf(f, "{\n  \"scene\": ");
  put_string(f, x->scene_path);
  fprintf(f, ",\n  \"output\": ");
  put_string(f, x->out_path);
  fprintf(f, ",\n  \"frame\": %d,\n  \"mode\": \"%s\",\n  \"integrator\": \"%s\",\n", x->frame,
          scene_mode_name(s->mode), scene_integrator_name(s->integrator));
  fprintf(f, "  \"step_voxels\": %.9g,\n  \"seed\": %u,\n", (double)s->step, s->seed);
  put_stages(f, x->timings);
  put_photons(f, x);
  fprintf(f, "  \"peak_rss_bytes\": %llu,\n", (unsigned long long)sj_peak_rss());
  const ee_terms_t *e = x->error ? &x->error->terms : NULL;
  fprintf(f, "  \"error\": {\n");
  put_term(f, "estimate", e ? e->estimate : -1.0, 0);
  put_term(f, "noise", e ? e->noise : -1.0, 0);
  put_term(f, "step", e ? e->step : -1.0, 0);
  put_term(f, "filter", e && e->noise >= 0.0 ? e->filter : -1.0, 0);
  fprintf(f, "    \"batches\": %d,\n    \"twin_batches\": %d,\n", e ? e->batches : 0,
          e ? e->twin_batches : 0);
  /* what the estimate cost: the step twin, the batches' statistics */
  fprintf(f, "    \"ms_twin\": %.3f,\n    \"ms_statistics\": %.3f,\n",
          x->error ? x->error->ms_twin : 0.0, x->error ? x->error->ms_track : 0.0);
  fprintf(f, "    \"target\": %.6g,\n    \"time_budget_s\": %.6g\n  }\n}\n",
          (double)s->target_error, (double)s->time_budget_s);
}

int sj_write(const char *path, const sj_frame_t *x, bk_error_t *err) {
  char tmp[4200];
  bk_temp_path(path, tmp, sizeof tmp);
  FILE *f = fopen(tmp, "w");
  if (!f) return bk_fail(err, BK_ERR_RUNTIME, "--stats %s: cannot write: %s", path, strerror(errno));
  put_all(f, x);
  int bad = ferror(f);
  if (fclose(f) != 0 || bad) {
    remove(tmp);
    return bk_fail(err, BK_ERR_RUNTIME, "--stats %s: write failed", path);
  }
  return bk_commit_temp(tmp, path, err);
}
