/* adaptive.c: the adaptive bake (ad_bake): the pilot march, the
 * distribution (adaptive_pdf.c), the weighted march and the reconstruction
 * filter (adaptive_filter.c) on one prepared march setup. */
#define _POSIX_C_SOURCE 200809L
#include "adaptive.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "base/parallel.h"
#include "adaptive_internal.h"
#include "error_est.h"

void ad_bake_defaults(ad_bake_opts_t *o) {
  memset(o, 0, sizeof *o);
  o->filter = 1;
  o->max_radius = AD_DEFAULT_MAX_RADIUS;
  o->smooth_radius = AD_DEFAULT_SMOOTH_RADIUS;
  o->floor_fraction = AD_DEFAULT_FLOOR;
  o->pilot_cells = AD_PILOT_CELLS;
  o->noise_k = AD_DEFAULT_NOISE_K;
  o->importance = AD_IMPORTANCE_GRADIENT;
}

/* The grey march's counters to one float per voxel (grey_range), and one
 * float per voxel to RGB (colour_range), on every core. */
typedef struct scale_job {
  const uint64_t *acc; /* grey_range: 2 counters per voxel, radiance first */
  const float *in;     /* colour_range */
  float *out;
  float k[3];
} scale_job_t;

static void grey_range(void *arg, size_t lo, size_t hi) {
  const scale_job_t *j = arg;
  for (size_t v = lo; v < hi; v++) j->out[v] = (float)j->acc[2 * v] * j->k[0];
}

static void colour_range(void *arg, size_t lo, size_t hi) {
  const scale_job_t *j = arg;
  for (size_t v = lo; v < hi; v++) {
    j->out[3 * v] = j->in[v] * j->k[0];
    j->out[3 * v + 1] = j->in[v] * j->k[1];
    j->out[3 * v + 2] = j->in[v] * j->k[2];
  }
}

static int run_march(clh_context_t *cl, const pm_setup_t *s, uint64_t *acc, pm_stats_t *st,
                     bk_error_t *err) {
  return cl ? pm_run_cl(cl, s, acc, st, err) : pm_run_host(s, acc, st, err);
}

/* One adaptive bake: the prepared setup and its two marches, and what the
 * phases hand each other. */
typedef struct ad_run {
  clh_context_t *cl;
  const scene_t *scene;
  const volume_t *vol;
  const ad_bake_opts_t *opt;
  ad_stats_t *stats;
  pm_setup_t base, pilot, main;
  int levels;             /* the filter's largest level (half voxels) */
  int have_pilot, shift;  /* pilot cells of 2^shift voxels */
  grid_dims_t cd;         /* the pilot's coarse grid */
  size_t cv;              /* its cells */
  uint64_t *pacc, *masks; /* pilot accumulator and origin masks */
  uint64_t *work;         /* the pilot's photons and work per light-domain cell */
  float *tables;          /* one PDF table per light (at least one) */
  double pdf_min, pdf_max;
  int filter_on;
  float alpha;            /* adaptive.alpha */
  double grey_k;          /* a grey march's radiance per counter, summed over RGB */
  float *raw;             /* the weighted march's radiance before the filter */
  /* the output grids, which target mode's checks use as scratch first */
  float *radiance, *count, *weight, *radius;
} ad_run_t;

static int check_bake_inputs(const scene_t *scene, const ad_bake_opts_t *opt, bk_error_t *err) {
  if (scene->pilot < 0)
    return bk_fail(err, BK_ERR_INPUT, "%s: adaptive.pilot: expected a photon count >= 0, got %d",
                   scene->path, scene->pilot);
  if (!(scene->alpha >= 0.0f) || isinf(scene->alpha))
    return bk_fail(err, BK_ERR_INPUT, "%s: adaptive.alpha: expected a finite number >= 0, got %g",
                   scene->path, (double)scene->alpha);
  if (!(opt->max_radius >= 0.0f && opt->max_radius <= 0.5f * AD_FILTER_MAX_LEVEL))
    return bk_fail(err, BK_ERR_INPUT, "adaptive filter: largest radius %g: expected 0..%g voxels",
                   (double)opt->max_radius, 0.5 * AD_FILTER_MAX_LEVEL);
  return BK_OK;
}

/* Phase 1: the pilot, on coarse cells over the full-resolution field. */
static int pilot_phase(ad_run_t *r, bk_error_t *err) {
  const scene_t *scene = r->scene;
  ad_stats_t *stats = r->stats;
  r->shift = ad_pilot_shift(&r->base.dims, r->opt->pilot_cells);
  r->cd = ad_coarse_dims(&r->base.dims, r->shift);
  r->cv = grid_count(&r->cd);
  stats->coarse_shift = r->shift;
  stats->pilot_photons = scene->pilot;
  double t0 = bk_now_ms();
  r->have_pilot = scene->pilot > 0 && r->base.lights.count > 0;
  if (r->have_pilot) {
    int rc = pm_derive(&r->base, scene, (uint64_t)scene->pilot, &r->pilot, err);
    if (rc != BK_OK) return rc;
    pm_record_origins(&r->pilot, r->shift, NULL);
    r->masks = bk_calloc(pm_mask_count(&r->pilot), sizeof(uint64_t), "adaptive origin masks", err);
    r->pacc = bk_calloc(pm_acc_count(&r->pilot), sizeof(uint64_t), "adaptive pilot accumulator",
                        err);
    r->work = bk_calloc((size_t)r->pilot.lights.count * PM_CELL_WORK_PER_LIGHT,
                        sizeof(uint64_t), "adaptive pilot work", err);
    if (!r->masks || !r->pacc || !r->work) return BK_ERR_RUNTIME;
    r->pilot.masks = r->masks;
    r->pilot.cell_work = r->work;
    rc = run_march(r->cl, &r->pilot, r->pacc, &stats->pilot, err);
    if (rc != BK_OK) return rc;
  }
  stats->ms_pilot = bk_now_ms() - t0;
  return BK_OK;
}

/* What each selected pilot cell spreads over its origins (NULL: 1 each, for
 * AD_IMPORTANCE_UNIT), cv floats in *out, freed by the caller; prgb is the
 * pilot radiance per cell. */
static int pilot_importance(const ad_run_t *r, const float *prgb, float **out, bk_error_t *err) {
  const size_t CV = r->cv;
  const int importance = r->opt->importance;
  *out = NULL;
  if (importance == AD_IMPORTANCE_UNIT) return BK_OK;
  float *vw = bk_calloc(CV, 2 * sizeof(float), "adaptive importance", err);
  if (!vw) return BK_ERR_RUNTIME;
  *out = vw;
  int rc = ad_pilot_fields(&r->cd, prgb, r->opt->smooth_radius, vw + CV, vw, err);
  if (rc != BK_OK) return rc;
  for (size_t v = 0; v < CV; v++) {
    double x = importance == AD_IMPORTANCE_LUMINANCE ? vw[CV + v] : vw[v];
    vw[v] = (float)(importance == AD_IMPORTANCE_GRADIENT_23 ? pow(x, 2.0 / 3.0) : x);
  }
  return BK_OK;
}

/* The pilot's light for the scene's light scene_index, -1 when the pilot
 * has none (a faint light that got no pilot photon). */
static int pilot_light(const ad_run_t *r, int scene_index) {
  int p = -1;
  for (int q = 0; q < r->pilot.lights.count; q++)
    if (r->pilot.lights.scene_index[q] == scene_index) p = q;
  return p;
}

/* Light l's table (of the main march's lights: base's, the same photon
 * count) from the selection and the importance vw; the pilot's lights may
 * lack a faint light that got no pilot photon, which then keeps the uniform
 * PDF. Widens [pdf_min, pdf_max] to its cells. */
static int light_pdf(ad_run_t *r, int l, const uint8_t *sel, const float *vw, bk_error_t *err) {
  const int TF = LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y);
  ad_pdf_t pdf;
  int p = pilot_light(r, r->base.lights.scene_index[l]), rc;
  if (p >= 0) {
    double cost[LD_CELLS];
    ad_cell_costs(r->work + (size_t)p * PM_CELL_WORK_PER_LIGHT, cost);
    rc = ad_build_pdf(r->masks + (size_t)p * r->cv, sel, vw, cost, r->cv, r->opt->floor_fraction,
                      &pdf, err);
  } else {
    memset(&pdf, 0, sizeof pdf);
    double zero[LD_CELLS] = {0};
    rc = ad_pdf_from_weights(zero, LD_CELLS_X, LD_CELLS_Y, 1.0f, pdf.table, pdf.cell_pdf, err);
  }
  if (rc != BK_OK) return rc;
  memcpy(r->tables + (size_t)l * TF, pdf.table, TF * sizeof(float));
  if (bk_verbosity >= 2) {
    char line[LD_CELLS_X * 8 + 1];
    bk_log(2, "adaptive: light %d: pdf per cell (rows b, columns a), %zu selected cells "
              "with origin data", l, pdf.selected_reached);
    for (int y = 0; y < LD_CELLS_Y; y++) {
      int at = 0;
      for (int x = 0; x < LD_CELLS_X; x++)
        at += snprintf(line + at, sizeof line - at, " %6.2f", (double)pdf.cell_pdf[x + LD_CELLS_X * y]);
      bk_log(2, "  %s", line);
    }
  }
  for (int c = 0; c < LD_CELLS; c++) {
    r->pdf_min = fmin(r->pdf_min, pdf.cell_pdf[c]);
    r->pdf_max = fmax(r->pdf_max, pdf.cell_pdf[c]);
  }
  return BK_OK;
}

/* The distribution: selection on the pilot, one PDF per light; without a
 * pilot, uniform tables. */
static int pdf_phase(ad_run_t *r, bk_error_t *err) {
  const int TF = LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y);
  const int nl = r->base.lights.count > 0 ? r->base.lights.count : 1;
  float *prgb = NULL, *pscat = NULL, *vw = NULL;
  uint8_t *sel = NULL;
  int rc = BK_ERR_RUNTIME;
  double t0 = bk_now_ms();
  r->pdf_min = r->pdf_max = 1.0;
  if (!r->have_pilot) {
    double zero[LD_CELLS] = {0};
    for (int l = 0; l < nl; l++) {
      rc = ad_pdf_from_weights(zero, LD_CELLS_X, LD_CELLS_Y, 1.0f, r->tables + (size_t)l * TF,
                               NULL, err);
      if (rc != BK_OK) goto error;
    }
    goto done;
  }
  prgb = bk_calloc(r->cv, 3 * sizeof(float), "adaptive pilot radiance", err);
  pscat = bk_calloc(r->cv, sizeof(float), "adaptive pilot scattering", err);
  sel = bk_calloc(r->cv, 1, "adaptive selection", err);
  if (!prgb || !pscat || !sel) goto error;
  ad_coarse_fields(&r->pilot, r->pacc, r->vol, r->shift, prgb, pscat);
  ad_select_opts_t so = {r->scene->gradient_threshold, r->scene->luminance_threshold,
                         r->opt->smooth_radius};
  rc = ad_select_voxels(&r->cd, prgb, pscat, &so, sel, &r->stats->select, err);
  if (rc != BK_OK) goto error;
  rc = pilot_importance(r, prgb, &vw, err);
  if (rc != BK_OK) goto error;
  r->pdf_min = 1e30;
  r->pdf_max = 0.0;
  for (int l = 0; l < r->base.lights.count; l++) {
    rc = light_pdf(r, l, sel, vw, err);
    if (rc != BK_OK) goto error;
  }
done:
  r->stats->pdf_min = (float)r->pdf_min;
  r->stats->pdf_max = (float)r->pdf_max;
  r->stats->ms_distribution = bk_now_ms() - t0;
  rc = BK_OK;
error:
  free(prgb);
  free(pscat);
  free(sel);
  free(vw);
  return rc;
}

/* After the weighted march: its sums acc unpacked into the photon count
 * and mean weight per voxel, and the radiance (r->raw, the march's channels,
 * when the filter follows; else `radiance`, RGB). */
static int unpack_phase(ad_run_t *r, const uint64_t *acc, float *radiance, float *count,
                        float *weight, bk_error_t *err) {
  const size_t V = r->base.voxels;
  const int C = r->main.channels;
  r->filter_on = r->opt->filter && r->alpha > 0.0f && r->levels > 0;
  /* grey: the filter works on the one channel the march carried (its
   * luminance is proportional), and colours the result after */
  r->grey_k = r->main.to_radiance[0] + r->main.to_radiance[1] + r->main.to_radiance[2];
  if (r->filter_on) {
    if (!r->raw && !(r->raw = bk_calloc(V, (size_t)C * sizeof(float), "adaptive raw radiance", err)))
      return BK_ERR_RUNTIME;
    if (C == 1) {
      scale_job_t job = {acc, NULL, r->raw, {(float)r->grey_k, 0.0f, 0.0f}};
      bk_parallel(V, BK_GRAIN, grey_range, &job);
    } else
      pm_to_radiance(&r->main, acc, r->raw, 3);
  } else {
    pm_to_radiance(&r->main, acc, radiance, 3);
  }
  pm_unpack_weights(&r->main, acc, count, weight);
  return BK_OK;
}

/* The allocation loop over the pilot's origin data: each main light's
 * pilot light, as light_pdf finds it. */
static int start_loop(ad_run_t *r, ad_loop_t *loop, bk_error_t *err) {
  int pilot_of[SCENE_MAX_LIGHTS];
  for (int l = 0; l < r->main.lights.count && l < SCENE_MAX_LIGHTS; l++)
    pilot_of[l] = pilot_light(r, r->main.lights.scene_index[l]);
  return ad_loop_init(loop, r->main.lights.count, r->shift, &r->cd, r->masks, r->work, pilot_of,
                      r->tables, r->opt->floor_fraction, err);
}

/* The loop rebuilds the tables from 2 batches' spread before a third: a
 * fixed bake of fewer than 3 batches never does (2 is the default). */
static void warn_no_retable(const scene_t *scene, const bt_options_t *bo) {
  const int open = scene->target_error > 0.0f || scene->time_budget_s > 0.0f;
  const int b = scene_batches(scene, bt_per_voxel(bo->error_grid, bo->shard_count));
  if (!open && b < 3)
    bk_warn("%s: adaptive.tables \"measured\" rebuilds the sampling tables from the spread of "
            "2 batches before the next: with %d batch(es) it never does, and the pilot's "
            "tables are used; set photons.batches to 3 or more, or a target error or time "
            "budget", scene->path, b);
}

static int target_check(void *ctx, int done, const uint64_t *acc, float *half_a, ee_terms_t *t,
                        bk_error_t *err);

/* Phase 2: warped Hammersley photons of weight 1/pdf in independent
 * batches (batches.h: each a rotated Hammersley set, a whole estimate), then
 * unpack_phase; a shard marches its share of every batch and keeps the
 * sums instead. */
static int weighted_phase(ad_run_t *r, float *radiance, float *count, float *weight,
                          bk_error_t *err) {
  ad_stats_t *stats = r->stats;
  pm_sums_t *shard = r->opt->sums;
  bt_options_t bo = {0};
  bo.shard_index = r->opt->shard_index, bo.shard_count = r->opt->shard_count, bo.sums = shard;
  bo.error_grid = r->opt->error_grid;
  bo.halves = r->filter_on && !shard && scene_batches(r->scene, bt_per_voxel(bo.error_grid, bo.shard_count)) != 1;
  bo.w_max = 1.0 / r->pdf_min;
  bo.photon_limit = PM_TABLES_MAX_PHOTONS;
  bo.t_start = r->opt->t_start;
  double t0 = bk_now_ms();
  ad_loop_t loop;
  memset(&loop, 0, sizeof loop);
  int rc = pm_derive(&r->base, r->scene, (uint64_t)r->scene->photon_count, &r->main, err);
  if (rc != BK_OK) return rc;
  if (bo.halves && r->scene->target_error > 0.0f) /* stop on the filtered grid's error */
    bo.target_terms = target_check, bo.target_ctx = r;
  if (r->opt->retable && r->have_pilot && !shard) {
    bo.w_max = 1.0 / r->opt->floor_fraction; /* every table keeps the floor */
    bo.retable = ad_loop_retable, bo.retable_ctx = &loop;
    warn_no_retable(r->scene, &bo);
  }
  rc = pm_sample_tables(&r->main, r->tables, bo.w_max, bt_photons_at_most(r->scene, &bo), err);
  if (rc == BK_OK && bo.retable) rc = start_loop(r, &loop, err);
  if (rc != BK_OK) return rc;
  stats->ms_generate += bk_now_ms() - t0;
  t0 = bk_now_ms();
  uint64_t *acc = bk_calloc(pm_acc_count(&r->main), sizeof(uint64_t), "adaptive accumulator", err);
  rc = BK_ERR_RUNTIME;
  if (!acc) goto error;
  if (r->main.lights.count > 0) {
    rc = bt_march(r->cl, r->scene, &r->main, &bo, acc, &stats->error, &stats->march, err);
    stats->retabled = loop.rebuilt;
    if (rc != BK_OK) goto error;
  }
  if (shard) {
    pm_sums_keep(&r->main, acc, shard);
    acc = NULL;
  } else {
    rc = unpack_phase(r, acc, radiance, count, weight, err);
  }
  /* the twins and the batch statistics are the error estimate's row */
  stats->ms_march = bk_now_ms() - t0 - stats->error.ms_twin - stats->error.ms_track;
error:
  ad_loop_free(&loop);
  free(acc);
  return rc;
}

/* filter_error's per-voxel passes, over voxels [v0, v1) (bk_parallel). */
typedef struct halves_job {
  const float *raw, *radiance; /* the raw mean (C channels), the filtered radiance (RGB) */
  float *half_a, *half_b;      /* half A's sums in, the halves' means out; or luminance out */
  int C;
  float to_sum, na, nb;
} halves_job_t;

/* The halves' means: A's from its sums, B's as the whole's sum less A's. */
static void halves_range(void *ctx, size_t v0, size_t v1) {
  const halves_job_t *j = ctx;
  for (size_t v = v0; v < v1; v++) {
    const float *x = j->raw + (size_t)j->C * v;
    const float lum = j->C == 1 ? x[0] : ad_luminance(x[0], x[1], x[2]);
    const float sum_a = j->half_a[v];
    j->half_a[v] = sum_a / j->na;
    j->half_b[v] = (lum * j->to_sum - sum_a) / j->nb; /* at v, read from C v */
  }
}

/* The filtered radiance's luminance, into half_a. */
static void luminance_range(void *ctx, size_t v0, size_t v1) {
  const halves_job_t *j = ctx;
  for (size_t v = v0; v < v1; v++)
    j->half_a[v] = ad_luminance(j->radiance[3 * v], j->radiance[3 * v + 1], j->radiance[3 * v + 2]);
}

/* The two halves of the batches filtered as the whole was (at its radii:
 * a linear map, ad_filter_fixed_lattice) and the filter's terms
 * (ee_filter_terms) from them and the filtered radiance, on the even
 * lattice that the noise term samples too (an eighth of the voxels). The
 * luminance sum of all batches is the raw mean's (r->raw) times B: no pass
 * over the march's sums for it. The halves' means are made in place of
 * what they come from (res->half_a, r->raw: done with once the filter
 * ran), once the lattice has its copy, and the filtered radiance's
 * luminance, to be filtered again, in half A's: no third grid. */
static int filter_error(ad_run_t *r, const float *radiance, const float *radius,
                        bk_error_t *err) {
  bt_result_t *res = &r->stats->error;
  const grid_dims_t *d = &r->base.dims;
  const size_t V = r->base.voxels;
  const size_t L = (size_t)((d->nx + 1) / 2) * ((d->ny + 1) / 2) * ((d->nz + 1) / 2);
  const int B = res->batches, C = r->main.channels;
  const float na = (float)((B + 1) / 2), nb = (float)(B / 2);
  /* raw -> the luminance sum: grey raw is one channel that colour_range
   * scales by to_radiance / grey_k */
  const double *k = r->main.to_radiance;
  const float to_sum = (float)B * (C == 1 ? (float)((EE_LUM_R * k[0] + EE_LUM_G * k[1] +
                                                     EE_LUM_B * k[2]) / r->grey_k)
                                          : 1.0f);
  float *lat = bk_calloc(6 * L, sizeof(float), "adaptive error: lattice", err);
  if (!lat) return BK_ERR_RUNTIME;
  float *fa = lat, *fb = lat + L, *all = lat + 2 * L, *half_a = lat + 3 * L, *f = lat + 4 * L;
  ee_lattice_gather(d, r->raw, C, all);
  for (size_t l = 0; l < L; l++) all[l] *= to_sum;
  ee_lattice_gather(d, res->half_a, 1, half_a);
  ee_lattice_gather(d, radiance, 3, f);
  float *half_b = r->raw;
  halves_job_t job = {r->raw, radiance, res->half_a, half_b, C, to_sum, na, nb};
  /* in place: RGB means land below the sums still to read, so in order */
  if (C == 1) bk_parallel(V, BK_GRAIN, halves_range, &job);
  else halves_range(&job, 0, V);
  const float *in[2] = {res->half_a, half_b};
  float *out[2] = {fa, fb};
  int rc = ad_filter_fixed_lattice(d, in, 2, radius, r->levels, out, err);
  /* with the noise test (radii chosen by the noise), the bias from the
   * filtered radiance filtered again (docs/error.md, "The filter") */
  float *wf = r->opt->noise_k >= 0.0f ? lat + 5 * L : NULL;
  if (rc == BK_OK && wf) {
    bk_parallel(V, BK_GRAIN, luminance_range, &job); /* half A's mean is done with */
    const float *lum_f = res->half_a;
    rc = ad_filter_fixed_lattice(d, &lum_f, 1, radius, r->levels, &wf, err);
  }
  if (rc == BK_OK) {
    ee_filter_terms(L, B, all, half_a, f, wf, fa, fb, &res->terms.noise, &res->terms.filter);
    ee_terms_t *e = &res->terms;
    if (e->noise >= 0.0 && e->step >= 0.0)
      e->estimate = sqrt(e->noise * e->noise + e->filter * e->filter + e->step * e->step);
  }
  free(lat);
  return rc;
}

/* After the filter: its terms in the estimate when it ran, the error grid
 * (the raw estimate's standard error), and the tracker freed. */
static int error_phase(ad_run_t *r, const float *radiance, const float *radius,
                       bk_error_t *err) {
  bt_result_t *res = &r->stats->error;
  double t0 = bk_now_ms();
  int rc = BK_OK;
  if (r->filter_on && res->half_a && res->batches > 1)
    rc = filter_error(r, radiance, radius, err);
  if (rc == BK_OK && r->opt->error_grid)
    res->error_grid = ee_take_error_grid(&res->full, res->batches);
  ee_tracker_free(&res->full);
  free(res->half_a);
  res->half_a = NULL;
  r->stats->ms_error = bk_now_ms() - t0;
  return rc;
}

/* Reconstruction: the filter on r->raw into radiance (RGB), or nothing when
 * it is off. */
static int filter_phase(ad_run_t *r, float *radiance, const float *count, const float *weight,
                        float *filter_radius, bk_error_t *err) {
  const size_t V = r->base.voxels;
  const int C = r->main.channels;
  const float alpha = r->alpha;
  float *filtered = NULL;
  int rc = BK_OK;
  double t0 = bk_now_ms();
  r->stats->filtered = r->filter_on;
  r->stats->max_radius = r->filter_on ? 0.5f * r->levels : 0.0f;
  if (r->filter_on) {
    filtered = C == 1 ? bk_calloc(V, sizeof(float), "adaptive filtered radiance", err) : radiance;
    if (!filtered) return BK_ERR_RUNTIME;
    rc = r->cl ? ad_filter_cl(r->cl, &r->base.dims, C, r->raw, count, weight, alpha,
                              r->opt->noise_k, r->levels, filtered, filter_radius, err)
               : ad_filter_host(&r->base.dims, C, r->raw, count, weight, alpha, r->opt->noise_k,
                                r->levels, filtered, filter_radius, err);
    if (rc == BK_OK && C == 1) {
      const double *k = r->main.to_radiance;
      scale_job_t job = {NULL, filtered, radiance,
                         {(float)(k[0] / r->grey_k), (float)(k[1] / r->grey_k),
                          (float)(k[2] / r->grey_k)}};
      bk_parallel(V, BK_GRAIN, colour_range, &job);
    }
    if (filtered != radiance) free(filtered);
  } else if (filter_radius) {
    memset(filter_radius, 0, V * sizeof(float));
  }
  r->stats->ms_filter = bk_now_ms() - t0;
  return rc;
}

/* bt_options_t.target_terms: the estimate of the grid the bake would write
 * after `done` batches, made as at the end (the sums unpacked, filtered and
 * measured, into the output grids, which the end writes again), so that
 * target mode stops on the filtered grid's error, not on the raw mean's
 * (its plan stays on the raw noise: docs/error.md, "Steering"). */
static int target_check(void *ctx, int done, const uint64_t *acc, float *half_a, ee_terms_t *t,
                        bk_error_t *err) {
  ad_run_t *r = ctx;
  bt_result_t *res = &r->stats->error; /* set only with the filter and its halves */
  double keep[3];
  memcpy(keep, r->main.to_radiance, sizeof keep);
  for (int c = 0; c < 3; c++) r->main.to_radiance[c] /= (double)done; /* the mean's, as finish */
  float *keep_half = res->half_a;
  const int keep_batches = res->batches;
  res->half_a = half_a, res->batches = done, res->terms = *t;
  int rc = unpack_phase(r, acc, r->radiance, r->count, r->weight, err);
  if (rc == BK_OK) rc = filter_phase(r, r->radiance, r->count, r->weight, r->radius, err);
  if (rc == BK_OK) rc = filter_error(r, r->radiance, r->radius, err);
  if (rc == BK_OK) *t = res->terms;
  memcpy(r->main.to_radiance, keep, sizeof keep);
  res->half_a = keep_half, res->batches = keep_batches;
  bk_log(2, "target error %g: %d batches: filtered estimate %.4f (noise %.4f, filter %.4f)",
         (double)r->scene->target_error, done, t->estimate, t->noise, t->filter);
  return rc;
}

/* The "error estimate" row: the batches' noise (of the filtered estimate
 * when the filter ran), the filter's bias and the step term. */
static void report_error(const ad_stats_t *stats, bk_timings_t *timings) {
  const bt_result_t *res = &stats->error;
  const ee_terms_t *t = &res->terms;
  double ms = res->ms_twin + res->ms_track + stats->ms_error;
  bk_log(2, "error estimate: twins %.0f ms, batch statistics %.0f ms, filter terms %.0f ms",
         res->ms_twin, res->ms_track, stats->ms_error);
  char step[48];
  if (res->step_exact) snprintf(step, sizeof step, "step 0 (exact)");
  else snprintf(step, sizeof step, "step %.4f (%d twins)", t->step, t->twin_batches);
  if (t->estimate < 0.0)
    bk_timings_add(timings, "error estimate", ms,
                   "unknown: %d batch(es), noise needs 2 (photons.batches)", t->batches);
  else if (stats->filtered)
    bk_timings_add(timings, "error estimate", ms,
                   "error %.4f = filtered noise %.4f (%d batches) + filter bias %.4f + %s",
                   t->estimate, t->noise, t->batches, t->filter, step);
  else
    bk_timings_add(timings, "error estimate", ms, "error %.4f = noise %.4f (%d batches) + %s",
                   t->estimate, t->noise, t->batches, step);
}

/* The timing rows and the summary line. */
static void report(const ad_run_t *r, bk_timings_t *timings) {
  const ad_stats_t *stats = r->stats;
  const int pilot = r->have_pilot ? r->scene->pilot : 0;
  const char *where = r->cl ? "" : ", host C";
  if (timings && r->base.fields_kept == 2) {
    bk_timings_add(timings, "octree", stats->ms_octree, "reused from frame %d (volume unchanged)",
                   r->base.fields_frame);
    bk_timings_mark_reused(timings, r->base.fields_frame);
  } else if (timings) {
    bk_timings_add(timings, "octree", stats->ms_octree, "%s",
                   r->base.has_refraction ? "constant-block pyramid of n, n/grad n field"
                                          : "n constant: one straight DDA per photon");
  }
  if (timings) {
    bk_timings_add(timings, "pilot marching", stats->ms_pilot,
                   "%d pilot photons, origin data on %dx%dx%d cells of %d^3 voxels", pilot,
                   r->cd.nx, r->cd.ny, r->cd.nz, 1 << r->shift);
    bk_timings_add(timings, "photon distribution", stats->ms_distribution,
                   "%zu cells selected, pdf %.2f..%.2f%s", stats->select.selected, r->pdf_min,
                   r->pdf_max, stats->retabled ? ", then rebuilt after each batch" : "");
    bk_timings_add(timings, "photon generation", stats->ms_generate,
                   "%d light(s), in-kernel Hammersley warped by the PDF", r->base.lights.count);
    double sec = stats->ms_march > 0.0 ? stats->ms_march / 1000.0 : 1e-9;
    bk_timings_add(timings, "photon marching", stats->ms_march,
                   "%llu photons in %d batches of %llu, %.0f M voxels/s%s",
                   (unsigned long long)stats->march.photons, stats->error.batches,
                   (unsigned long long)stats->error.batch_photons,
                   stats->march.voxels / sec * 1e-6, where);
    if (r->filter_on)
      bk_timings_add(timings, "filtering", stats->ms_filter, "alpha %g, radius <= %g voxels%s",
                     (double)r->alpha, 0.5 * r->levels, where);
    else
      bk_timings_add(timings, "filtering", stats->ms_filter, "off");
    report_error(stats, timings);
  }
  bk_log(2,
         "adaptive: pilot %d photons on %dx%dx%d cells, thresholds gradient %g /m, luminance %g; "
         "%zu of %zu cells selected; pdf %.3f..%.3f; %llu photons marched",
         pilot, r->cd.nx, r->cd.ny, r->cd.nz, (double)stats->select.gradient_threshold,
         (double)stats->select.luminance_threshold, stats->select.selected,
         stats->select.considered, r->pdf_min, r->pdf_max,
         (unsigned long long)stats->march.photons);
}

int ad_bake(clh_context_t *cl, const scene_t *scene, const volume_t *vol,
            const ad_bake_opts_t *opt, float *radiance, float *photon_count, float *photon_weight,
            float *filter_radius, ad_stats_t *stats, bk_timings_t *timings, bk_error_t *err) {
  ad_run_t r;
  ad_stats_t local;
  ad_bake_opts_t defaults;
  float *count = NULL, *weight = NULL, *radius = NULL;
  if (!stats) stats = &local;
  memset(stats, 0, sizeof *stats);
  if (!opt) {
    ad_bake_defaults(&defaults);
    opt = &defaults;
  }
  int rc = check_bake_inputs(scene, opt, err);
  if (rc != BK_OK) return rc;
  r = (ad_run_t){.cl = cl, .scene = scene, .vol = vol, .opt = opt, .stats = stats,
                 .alpha = scene->alpha, .levels = (int)(2.0f * opt->max_radius + 0.5f)};
  r.filter_on = opt->filter && r.alpha > 0.0f && r.levels > 0;
  rc = pm_prepare_kept(scene, vol, opt->fields, &r.base, NULL, &stats->march, err);
  if (rc != BK_OK) return rc;
  stats->ms_octree = stats->march.ms_octree;
  stats->ms_generate = stats->march.ms_generate;
  const size_t V = r.base.voxels;
  const int nl = r.base.lights.count > 0 ? r.base.lights.count : 1;
  rc = BK_ERR_RUNTIME;
  r.tables = bk_calloc((size_t)nl, LD_TABLE_FLOATS(LD_CELLS_X, LD_CELLS_Y) * sizeof(float),
                       "adaptive PDF tables", err);
  if (!r.tables) goto error;
  if ((rc = pilot_phase(&r, err)) != BK_OK || (rc = pdf_phase(&r, err)) != BK_OK) goto error;
  rc = BK_ERR_RUNTIME;
  if (!opt->sums) { /* a shard unpacks nothing */
    count = photon_count ? photon_count : bk_calloc(V, sizeof(float), "photon count grid", err);
    weight = photon_weight ? photon_weight : bk_calloc(V, sizeof(float), "photon weight grid", err);
    if (!count || !weight) goto error;
  }
  /* the error estimate filters at the filter's radii: kept here when the
   * caller does not want them */
  if (!opt->sums && r.filter_on && !filter_radius &&
      !(radius = bk_calloc(V, sizeof(float), "adaptive filter radius", err)))
    goto error;
  if (!radius) radius = filter_radius;
  r.radiance = radiance, r.count = count, r.weight = weight, r.radius = radius;
  if ((rc = weighted_phase(&r, radiance, count, weight, err)) != BK_OK) goto error;
  /* the march is done: its fields make room for the filter's means */
  pm_setup_free_fields(&r.base);
  if ((!opt->sums && (rc = filter_phase(&r, radiance, count, weight, radius, err)) != BK_OK) ||
      (!opt->sums && (rc = error_phase(&r, radiance, radius, err)) != BK_OK))
    goto error;
  report(&r, timings);
  rc = BK_OK;
error:
  ee_tracker_free(&stats->error.full);
  free(stats->error.half_a);
  stats->error.half_a = NULL;
  if (rc != BK_OK) {
    free(stats->error.error_grid);
    stats->error.error_grid = NULL;
  }
  free(r.pacc);
  free(r.masks);
  free(r.work);
  free(r.tables);
  free(r.raw);
  if (count != photon_count) free(count);
  if (weight != photon_weight) free(weight);
  if (radius != filter_radius) free(radius);
  pm_setup_free(&r.base);
  return rc;
}

int ad_finish(clh_context_t *cl, const grid_dims_t *dims, const pm_sums_t *sums,
              const ad_bake_opts_t *opt, float alpha, float *radiance, float *photon_count,
              float *photon_weight, float *filter_radius, ad_stats_t *stats, bk_error_t *err) {
  ad_run_t r = {.cl = cl, .opt = opt, .stats = stats, .alpha = alpha,
                .levels = (int)(2.0f * opt->max_radius + 0.5f)};
  r.base.voxels = sums->voxels;
  r.base.dims = *dims;
  pm_sums_setup(sums, &r.main);
  int rc = unpack_phase(&r, sums->acc, radiance, photon_count, photon_weight, err);
  if (rc == BK_OK) rc = filter_phase(&r, radiance, photon_count, photon_weight, filter_radius, err);
  free(r.raw);
  return rc;
}
