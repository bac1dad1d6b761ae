# Multiple scattering (tests/test_scatter.c): energy conservation, the
# diffusion limit, bounces 0 = single scattering bit for bit, the "auto"
# rule, phase sampling, reproducibility; each a few seconds on 2 cores.
add_executable(test_scatter ${BAKER_TEST_DIR}/test_scatter.c)
target_link_libraries(test_scatter PRIVATE bakercore)
foreach(path host cl)
  add_test(NAME scatter_energy_${path} COMMAND test_scatter energy ${path})
  add_test(NAME scatter_flux_${path} COMMAND test_scatter flux ${path})
  add_test(NAME scatter_camera_${path} COMMAND test_scatter camera ${path})
endforeach()
add_test(NAME scatter_diffusion COMMAND test_scatter diffusion cl)
add_test(NAME scatter_diffusion_hg COMMAND test_scatter diffusion_hg cl)
add_test(NAME scatter_first_leg COMMAND test_scatter first_leg)
add_test(NAME scatter_auto COMMAND test_scatter auto)
add_test(NAME scatter_phase COMMAND test_scatter phase)
add_test(NAME scatter_object_g COMMAND test_scatter object_g)
add_test(NAME scatter_reproducible COMMAND test_scatter reproducible cl)

get_property(SCATTER_TESTS DIRECTORY PROPERTY TESTS)
list(FILTER SCATTER_TESTS INCLUDE REGEX "^scatter_")
set_tests_properties(${SCATTER_TESTS} PROPERTIES
  ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_CURRENT_BINARY_DIR}/march_kernel_cache" TIMEOUT 120)

# Against Mitsuba 3 (scripts/bench_mitsuba --quick: small fog scenes, g 0 and
# 0.3 all orders, g 0.8 single scattering and all orders looking into the
# light, totals within 2%); skipped when mitsuba is not importable
# (scripts/setup_mitsuba.sh installs it into build/mitsuba-venv).
add_test(NAME mitsuba_small
         COMMAND ${CMAKE_SOURCE_DIR}/scripts/bench_mitsuba --quick --baker $<TARGET_FILE:baker>
                 --out ${CMAKE_CURRENT_BINARY_DIR}/mitsuba-small)
set_tests_properties(mitsuba_small PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 300
  ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_CURRENT_BINARY_DIR}/kernel-cache")
