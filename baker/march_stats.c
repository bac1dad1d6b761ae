/* march_stats.c: what the march counts (see march.h): each photon's
 * outcome, its energy accounting under multiple scattering, its work per
 * light-domain cell, and the scattering report. */
#include "march.h"

#include "integrators.h"
#include "kernels/light_sample.h"

void pm_stats_add(pm_stats_t *st, const pm_result *r) {
  st->photons++;
  switch (r->fate) {
  case PM_FATE_MISSED: st->missed_grid++; break;
  case PM_FATE_LEFT: st->left_grid++; break;
  case PM_FATE_ABSORBED: st->absorbed++; break;
  default: st->step_limit++; break;
  }
  st->steps += r->steps;
  st->voxels += r->voxels;
  st->path_voxels += r->path;
}

BK_STATIC_ASSERT((PM_MAX_STEPS >> SCENE_MIN_STEP_LOG2) >= 64,
                 "scene.h SCENE_MIN_STEP: 64 voxels of curved path within the step limit");

void pm_warn_step_limit(const scene_t *scene, const pm_stats_t *st) {
  if (!st->photons || st->step_limit * 100 < st->photons) return;
  bk_warn("%s: %.1f%% of the photons stopped at the step limit (%d steps, or %g grid diagonals "
          "of path) and the light they still carried is missing from the grid: light trapped "
          "by total internal reflection, a random walk that long, or photons.step (%g voxels) "
          "too fine for the band where n varies (grid.ior_smoothing %g voxels)",
          scene->path, 100.0 * (double)st->step_limit / (double)st->photons, PM_MAX_STEPS,
          (double)PM_MAX_PATH_DIAGONALS, (double)scene->step, (double)scene->ior_smoothing);
}

uint64_t pm_work(unsigned integrator, uint64_t steps, uint64_t voxels) {
  const integrator_kind_t *k = integrator_of_device(integrator);
  return steps * (k ? k->evals : 1u) + voxels;
}

void pm_count_cell_work(const pm_setup_t *s, uint64_t slot, const pm_result *r) {
  if (!s->cell_work) return;
  const ph_light *lights = s->lights.lights;
  const bk_uint photon = ph_photon_of_slot(lights, s->params.light_count, (bk_uint)slot);
  const bk_uint l = ph_light_of(lights, s->params.light_count, photon);
  float a, b;
  ph_point(lights + l, photon - lights[l].first, &a, &b);
  const int c = ld_cell_of(a, b);
  uint64_t *w = s->cell_work + (size_t)l * PM_CELL_WORK_PER_LIGHT;
  w[c]++;
  w[LD_CELLS + c] += pm_work(s->params.integrator, r->steps, r->voxels);
}

void pm_stats_add_tally(pm_stats_t *st, const ms_tally *t) {
  st->entered += t->entered;
  st->escaped += t->escaped;
  st->deposit_first += t->first;
  st->deposit_later += t->later;
  st->events += t->events;
}

double pm_scattered_share(const pm_stats_t *st) {
  double all = st->deposit_first + st->deposit_later;
  return all > 0.0 ? st->deposit_later / all : 0.0;
}

/* What multiple scattering did: a timing row (no time of its own: the
 * march's) and a log line. */
void pm_report_scattering(const pm_setup_t *s, pm_stats_t *stats, bk_timings_t *timings) {
  const ms_setup_t *ms = &s->ms;
  if (!ms->params.max_bounces) {
    if (timings)
      bk_timings_add(timings, "scattering", 0.0, "single scattering (bounces 0%s, order ratio %.3g)",
                     ms->auto_chosen ? " by auto" : "", ms->ratio);
    return;
  }
  double share = pm_scattered_share(stats);
  if (timings)
    bk_timings_add(timings, "scattering", 0.0,
                   "up to %u events%s, %.2f per photon; %.1f%% of the deposit after the first "
                   "event",
                   ms->params.max_bounces, ms->auto_chosen ? " (auto)" : "",
                   stats->photons ? (double)stats->events / (double)stats->photons : 0.0,
                   100.0 * share);
  bk_log(1, "march: multiple scattering: up to %u events per photon%s, %.1f%% of the deposited "
            "energy after the first scattering event; %.4g W entered the grid, %.4g W left it",
         ms->params.max_bounces, ms->auto_chosen ? " (auto)" : "", 100.0 * share, stats->entered,
         stats->escaped);
}
