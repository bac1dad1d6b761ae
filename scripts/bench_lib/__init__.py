"""scripts/bench's parts: runner (child processes, baker's printed tables),
metrics (grid error, energy, Pareto front, power-law fits), scenes (scene
variants for the sweep and the extremes), report (tables) and plots."""
