/* integrators.c: Euler and RK4 (see integrators.h). */
#include "integrators.h"

#include <string.h>

const integrator_kind_t integrator_kinds[INTEGRATOR_KIND_COUNT] = {
    {"euler", INTEGRATOR_EULER, 0, "INTEGRATOR=0", 1}, /* the paper's explicit scheme */
    {"rk4", INTEGRATOR_RK4, 1, "INTEGRATOR=1", 4}, /* classical Runge–Kutta */
};

const integrator_kind_t *integrator_find(const char *name) {
  for (int i = 0; i < INTEGRATOR_KIND_COUNT; i++)
    if (strcmp(integrator_kinds[i].name, name) == 0) return &integrator_kinds[i];
  return NULL;
}

const integrator_kind_t *integrator_kind(integrator_t i) {
  return (int)i >= 0 && (int)i < INTEGRATOR_KIND_COUNT ? &integrator_kinds[i] : NULL;
}

const integrator_kind_t *integrator_of_device(unsigned device) {
  for (int i = 0; i < INTEGRATOR_KIND_COUNT; i++)
    if (integrator_kinds[i].device == device) return &integrator_kinds[i];
  return NULL;
}
