/* integrators.h: the ray-equation integrators, as one table.
 *
 * Each row names an integrator as the scene file and the command line do
 * (`photons.integrator`, `--integrator`), gives its integrator_t, and the
 * value of the kernels' INTEGRATOR flag that selects it (kernels/photon_march.h,
 * kernels/view_march.h: 0 Euler, 1 RK4). A new integrator is one row here plus its
 * step in the kernels. */
#ifndef BAKER_INTEGRATORS_H
#define BAKER_INTEGRATORS_H

#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct integrator_kind {
  const char *name;        /* "euler", "rk4" */
  integrator_t id;         /* its row in integrator_kinds[] */
  unsigned device;         /* -DINTEGRATOR=device, pm_params.integrator */
  const char *define;      /* that flag as text, "INTEGRATOR=1" */
  unsigned evals;          /* field evaluations per step: the march's work (pm_work) */
} integrator_kind_t;

#define INTEGRATOR_KIND_COUNT 2
extern const integrator_kind_t integrator_kinds[INTEGRATOR_KIND_COUNT];

/* The integrator named `name`, or NULL. */
const integrator_kind_t *integrator_find(const char *name);
/* The row of i; NULL outside the table. */
const integrator_kind_t *integrator_kind(integrator_t i);
/* The row whose device value (pm_params.integrator) is `device`, or NULL. */
const integrator_kind_t *integrator_of_device(unsigned device);

#ifdef __cplusplus
}
#endif
#endif
