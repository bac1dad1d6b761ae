/* adaptive.c: the adaptive bake (ad_bake): the pilot march, the
 * distribution (adaptive_pdf.c), the weighted march and the reconstruction
 * filter (adaptive_filter.c) on one prepared march setup. */
#define _POSIX_C_SOURCE 200809L
#include "adaptive.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

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

/* The pilot grid's coarsening: cells of 2^shift voxels a side, the fewest
 * that bring the longest axis to pilot_cells cells. */
static int pilot_shift(const grid_dims_t *d, int pilot_cells) {
  int longest = d->nx > d->ny ? d->nx : d->ny;
  if (d->nz > longest) longest = d->nz;
  int s = 0;
  while (s < 10 && pilot_cells > 0 && (longest >> s) > pilot_cells) s++;
  return s;
}

/* The pilot's coarse grid: cells of 2^shift voxels a side over the same
 * corner (the last ones may stick out of the grid). */
static grid_dims_t coarse_dims(const grid_dims_t *d, int shift) {
  grid_dims_t c = *d;
  int m = (1 << shift) - 1;
  c.nx = (d->nx + m) >> shift;
  c.ny = (d->ny + m) >> shift;
  c.nz = (d->nz + m) >> shift;
  c.voxel_size = d->voxel_size * (float)(1 << shift);
  return c;
}

/* The largest grey scattering coefficient of the voxels of each coarse
 * cell, layers [lo, hi) of cells along z (one range per core: the layers
 * own disjoint cells). */
typedef struct scat_job {
  const volume_t *vol;
  int shift;
  float *scat;
} scat_job_t;

static void coarse_scattering_range(void *arg, size_t lo, size_t hi) {
  const scat_job_t *j = arg;
  const grid_dims_t *d = &j->vol->dims;
  const int shift = j->shift;
  grid_dims_t c = coarse_dims(d, shift);
  for (size_t v = grid_index(&c, 0, 0, (int)lo); v < grid_index(&c, 0, 0, (int)hi); v++)
    j->scat[v] = 0.0f;
  int k1 = (int)hi << shift;
  if (k1 > d->nz) k1 = d->nz;
  for (int k = (int)lo << shift; k < k1; k++)
    for (int jy = 0; jy < d->ny; jy++) {
      size_t row = grid_index(d, 0, jy, k);
      float *crow = j->scat + grid_index(&c, 0, jy >> shift, k >> shift);
      const float *s = j->vol->sigma_s + 3 * row;
      for (int i = 0; i < d->nx; i++) {
        float g = (s[3 * i] + s[3 * i + 1] + s[3 * i + 2]) * (1.0f / 3.0f);
        float *o = &crow[i >> shift];
        if (g > *o) *o = g;
      }
    }
}

/* Per coarse cell: the pilot's mean radiance over its voxels in the grid
 * (3 floats) and the largest grey scattering coefficient of those voxels. */
static void coarse_fields(const pm_setup_t *p, const uint64_t *acc, const volume_t *vol, int shift,
                          float *rgb, float *scat) {
  const grid_dims_t *d = &vol->dims;
  grid_dims_t c = coarse_dims(d, shift);
  const int ch = p->channels;
  scat_job_t job = {vol, shift, scat};
  pm_parallel((size_t)c.nz, 1, coarse_scattering_range, &job);
  for (int k = 0; k < c.nz; k++)
    for (int j = 0; j < c.ny; j++)
      for (int i = 0; i < c.nx; i++) {
        size_t v = grid_index(&c, i, j, k);
        /* voxels of this cell inside the grid */
        int ex = (i + 1) << shift > d->nx ? d->nx - (i << shift) : 1 << shift;
        int ey = (j + 1) << shift > d->ny ? d->ny - (j << shift) : 1 << shift;
        int ez = (k + 1) << shift > d->nz ? d->nz - (k << shift) : 1 << shift;
        double inv = 1.0 / ((double)ex * ey * ez);
        for (int q = 0; q < 3; q++)
          rgb[3 * v + q] = (float)((double)acc[ch * v + (ch == 1 ? 0 : q)] * p->to_radiance[q] * inv);
      }
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

int ad_bake(clh_context_t *cl, const scene_t *scene, const volume_t *vol,
            const ad_bake_opts_t *opt, float *radiance, float *photon_count, float *photon_weight,
            float *filter_radius, ad_stats_t *stats, bk_timings_t *timings, bk_error_t *err) {
  pm_setup_t base, pilot, main;
  ad_stats_t local;
  ad_bake_opts_t defaults;
  uint64_t *pacc = NULL, *masks = NULL, *acc = NULL;
  float *prgb = NULL, *pscat = NULL, *tables = NULL, *count = NULL, *weight = NULL;
  float *raw = NULL, *filtered = NULL, *vw = NULL;
  uint8_t *sel = NULL;
  double t0;
  memset(&base, 0, sizeof base);
  if (!stats) stats = &local;
  memset(stats, 0, sizeof *stats);
  if (!opt) {
    ad_bake_defaults(&defaults);
    opt = &defaults;
  }
  if (scene->pilot < 0)
    return bk_fail(err, BK_ERR_INPUT, "%s: adaptive.pilot: expected a photon count >= 0, got %d",
                   scene->path, scene->pilot);
  if (!(scene->alpha >= 0.0f) || isinf(scene->alpha))
    return bk_fail(err, BK_ERR_INPUT, "%s: adaptive.alpha: expected a finite number >= 0, got %g",
                   scene->path, (double)scene->alpha);
  if (!(opt->max_radius >= 0.0f && opt->max_radius <= 0.5f * AD_FILTER_MAX_LEVEL))
    return bk_fail(err, BK_ERR_INPUT, "adaptive filter: largest radius %g: expected 0..%g voxels",
                   (double)opt->max_radius, 0.5 * AD_FILTER_MAX_LEVEL);
  const int levels = (int)(2.0f * opt->max_radius + 0.5f);

  int rc = pm_prepare(scene, vol, &base, NULL, &stats->march, err);
  if (rc != BK_OK) return rc;
  stats->ms_octree = stats->march.ms_octree;
  stats->ms_generate = stats->march.ms_generate;
  const grid_dims_t *d = &base.dims;
  const size_t V = base.voxels;
  const int nl = base.lights.count > 0 ? base.lights.count : 1;
  const int TF = AD_TABLE_FLOATS(AD_CELLS_X, AD_CELLS_Y);
  rc = BK_ERR_RUNTIME;
  tables = bk_calloc((size_t)nl, TF * sizeof(float), "adaptive PDF tables", err);
  if (!tables) goto error;

  /* phase 1: the pilot, on coarse cells over the full-resolution field */
  const int shift = pilot_shift(d, opt->pilot_cells);
  const grid_dims_t cd = coarse_dims(d, shift);
  const size_t CV = grid_count(&cd);
  stats->coarse_shift = shift;
  stats->pilot_photons = scene->pilot;
  t0 = bk_now_ms();
  int have_pilot = scene->pilot > 0 && base.lights.count > 0;
  if (have_pilot) {
    rc = pm_derive(&base, scene, (uint64_t)scene->pilot, &pilot, err);
    if (rc != BK_OK) goto error;
    pm_use_pilot(&pilot, shift, NULL);
    rc = BK_ERR_RUNTIME;
    masks = bk_calloc(pm_mask_count(&pilot), sizeof(uint64_t), "adaptive origin masks", err);
    pacc = bk_calloc(pm_acc_count(&pilot), sizeof(uint64_t), "adaptive pilot accumulator", err);
    if (!masks || !pacc) goto error;
    pilot.masks = masks;
    rc = run_march(cl, &pilot, pacc, &stats->pilot, err);
    if (rc != BK_OK) goto error;
  }
  stats->ms_pilot = bk_now_ms() - t0;

  /* the distribution: selection on the pilot, one PDF per light */
  t0 = bk_now_ms();
  double pdf_min = 1.0, pdf_max = 1.0;
  if (have_pilot) {
    rc = BK_ERR_RUNTIME;
    prgb = bk_calloc(CV, 3 * sizeof(float), "adaptive pilot radiance", err);
    pscat = bk_calloc(CV, sizeof(float), "adaptive pilot scattering", err);
    sel = bk_calloc(CV, 1, "adaptive selection", err);
    if (!prgb || !pscat || !sel) goto error;
    coarse_fields(&pilot, pacc, vol, shift, prgb, pscat);
    ad_select_opts_t so = {scene->gradient_threshold, scene->luminance_threshold,
                           opt->smooth_radius};
    rc = ad_select_voxels(&cd, prgb, pscat, &so, sel, &stats->select, err);
    if (rc != BK_OK) goto error;
    if (opt->importance != AD_IMPORTANCE_UNIT) {
      rc = BK_ERR_RUNTIME;
      vw = bk_calloc(CV, 2 * sizeof(float), "adaptive importance", err);
      if (!vw) goto error;
      rc = ad_pilot_fields(&cd, prgb, opt->smooth_radius, vw + CV, vw, err);
      if (rc != BK_OK) goto error;
      for (size_t v = 0; v < CV; v++) {
        double x = opt->importance == AD_IMPORTANCE_LUMINANCE ? vw[CV + v] : vw[v];
        vw[v] = (float)(opt->importance == AD_IMPORTANCE_GRADIENT_23 ? pow(x, 2.0 / 3.0) : x);
      }
    }
    pdf_min = 1e30;
    pdf_max = 0.0;
    /* tables follow the main march's lights (base's: the same photon count);
     * the pilot's may lack a faint light that got no pilot photon, which
     * then keeps the uniform PDF */
    for (int l = 0; l < base.lights.count; l++) {
      ad_pdf_t pdf;
      int p = -1;
      for (int q = 0; q < pilot.lights.count; q++)
        if (pilot.lights.scene_index[q] == base.lights.scene_index[l]) p = q;
      if (p >= 0) {
        rc = ad_build_pdf(masks + (size_t)p * CV, sel, vw, CV, opt->floor_fraction, &pdf, err);
      } else {
        memset(&pdf, 0, sizeof pdf);
        double zero[AD_CELLS] = {0};
        rc = ad_pdf_from_weights(zero, AD_CELLS_X, AD_CELLS_Y, 1.0f, pdf.table, pdf.cell_pdf, err);
      }
      if (rc != BK_OK) goto error;
      memcpy(tables + (size_t)l * TF, pdf.table, TF * sizeof(float));
      if (bk_verbosity >= 2) {
        char line[AD_CELLS_X * 8 + 1];
        bk_log(2, "adaptive: light %d: pdf per cell (rows b, columns a), %zu selected cells "
                  "with origin data", l, pdf.selected_reached);
        for (int y = 0; y < AD_CELLS_Y; y++) {
          int at = 0;
          for (int x = 0; x < AD_CELLS_X; x++)
            at += snprintf(line + at, sizeof line - at, " %6.2f", (double)pdf.cell_pdf[x + AD_CELLS_X * y]);
          bk_log(2, "  %s", line);
        }
      }
      for (int c = 0; c < AD_CELLS; c++) {
        pdf_min = fmin(pdf_min, pdf.cell_pdf[c]);
        pdf_max = fmax(pdf_max, pdf.cell_pdf[c]);
      }
    }
  } else {
    double zero[AD_CELLS] = {0};
    for (int l = 0; l < nl; l++) {
      rc = ad_pdf_from_weights(zero, AD_CELLS_X, AD_CELLS_Y, 1.0f, tables + (size_t)l * TF, NULL,
                               err);
      if (rc != BK_OK) goto error;
    }
  }
  stats->pdf_min = (float)pdf_min;
  stats->pdf_max = (float)pdf_max;
  stats->ms_distribution = bk_now_ms() - t0;

  /* phase 2: warped Hammersley photons of weight 1/pdf */
  t0 = bk_now_ms();
  rc = pm_derive(&base, scene, (uint64_t)scene->photon_count, &main, err);
  if (rc != BK_OK) goto error;
  rc = pm_use_pdf(&main, tables, 1.0 / pdf_min, err);
  if (rc != BK_OK) goto error;
  stats->ms_generate += bk_now_ms() - t0;
  t0 = bk_now_ms();
  rc = BK_ERR_RUNTIME;
  acc = bk_calloc(pm_acc_count(&main), sizeof(uint64_t), "adaptive accumulator", err);
  count = photon_count ? photon_count : bk_calloc(V, sizeof(float), "photon count grid", err);
  weight = photon_weight ? photon_weight : bk_calloc(V, sizeof(float), "photon weight grid", err);
  if (!acc || !count || !weight) goto error;
  if (main.lights.count > 0) {
    rc = run_march(cl, &main, acc, &stats->march, err);
    if (rc != BK_OK) goto error;
  }
  const int C = main.channels;
  const int filter_on = opt->filter && scene->alpha > 0.0f && levels > 0;
  /* grey: the filter works on the one channel the march carried (its
   * luminance is proportional), and colours the result after */
  double grey_k = main.to_radiance[0] + main.to_radiance[1] + main.to_radiance[2];
  if (filter_on) {
    raw = bk_calloc(V, (size_t)C * sizeof(float), "adaptive raw radiance", err);
    if (!raw) goto error;
    if (C == 1) {
      scale_job_t job = {acc, NULL, raw, {(float)grey_k, 0.0f, 0.0f}};
      pm_parallel(V, PM_GRAIN, grey_range, &job);
    } else
      pm_to_radiance(&main, acc, raw);
  } else {
    pm_to_radiance(&main, acc, radiance);
  }
  pm_unpack_weights(&main, acc, count, weight);
  free(acc);
  acc = NULL;
  stats->ms_march = bk_now_ms() - t0;

  /* reconstruction */
  t0 = bk_now_ms();
  stats->filtered = filter_on;
  stats->max_radius = filter_on ? 0.5f * levels : 0.0f;
  if (filter_on) {
    filtered = C == 1 ? bk_calloc(V, sizeof(float), "adaptive filtered radiance", err) : radiance;
    if (!filtered) goto error;
    rc = cl ? ad_filter_cl(cl, d, C, raw, count, weight, scene->alpha, opt->noise_k, levels,
                           filtered, filter_radius, err)
            : ad_filter_host(d, C, raw, count, weight, scene->alpha, opt->noise_k, levels,
                             filtered, filter_radius, err);
    if (rc != BK_OK) goto error;
    if (C == 1) {
      scale_job_t job = {NULL, filtered, radiance,
                         {(float)(main.to_radiance[0] / grey_k),
                          (float)(main.to_radiance[1] / grey_k),
                          (float)(main.to_radiance[2] / grey_k)}};
      pm_parallel(V, PM_GRAIN, colour_range, &job);
    }
  } else if (filter_radius) {
    memset(filter_radius, 0, V * sizeof(float));
  }
  stats->ms_filter = bk_now_ms() - t0;

  if (timings) {
    bk_timings_add(timings, "octree", stats->ms_octree, "%s",
                   base.has_refraction ? "constant-block pyramid of n, n/grad n field"
                                       : "n constant: one straight DDA per photon");
    bk_timings_add(timings, "pilot marching", stats->ms_pilot,
                   "%d pilot photons, origin data on %dx%dx%d cells of %d^3 voxels",
                   have_pilot ? scene->pilot : 0, cd.nx, cd.ny, cd.nz, 1 << shift);
    bk_timings_add(timings, "photon distribution", stats->ms_distribution,
                   "%zu cells selected, pdf %.2f..%.2f", stats->select.selected, pdf_min, pdf_max);
    bk_timings_add(timings, "photon generation", stats->ms_generate,
                   "%d light(s), in-kernel Hammersley warped by the PDF", base.lights.count);
    double sec = stats->ms_march > 0.0 ? stats->ms_march / 1000.0 : 1e-9;
    bk_timings_add(timings, "photon marching", stats->ms_march,
                   "%llu photons, %.0f M voxels/s%s", (unsigned long long)stats->march.photons,
                   stats->march.voxels / sec * 1e-6, cl ? "" : ", host C");
    if (filter_on)
      bk_timings_add(timings, "filtering", stats->ms_filter, "alpha %g, radius <= %g voxels%s",
                     (double)scene->alpha, 0.5 * levels, cl ? "" : ", host C");
    else
      bk_timings_add(timings, "filtering", stats->ms_filter, "off");
  }
  bk_log(2,
         "adaptive: pilot %d photons on %dx%dx%d cells, thresholds gradient %g /m, luminance %g; "
         "%zu of %zu cells selected; pdf %.3f..%.3f; %llu photons marched",
         have_pilot ? scene->pilot : 0, cd.nx, cd.ny, cd.nz,
         (double)stats->select.gradient_threshold, (double)stats->select.luminance_threshold,
         stats->select.selected, stats->select.considered, pdf_min, pdf_max,
         (unsigned long long)stats->march.photons);
  rc = BK_OK;
error:
  free(pacc);
  free(masks);
  free(acc);
  free(prgb);
  free(pscat);
  free(sel);
  free(vw);
  free(tables);
  free(raw);
  if (filtered != radiance) free(filtered);
  if (count != photon_count) free(count);
  if (weight != photon_weight) free(weight);
  pm_setup_free(&base);
  return rc;
}
