# Photon generation and marching (tests/test_march*.c): analytic truths on the
# host C path and on OpenCL (PoCL), each a few seconds on 2 cores.
add_executable(test_march ${BAKER_TEST_DIR}/test_march.c)
target_link_libraries(test_march PRIVATE bakercore)
add_executable(test_march_optics ${BAKER_TEST_DIR}/test_march_optics.c)
target_link_libraries(test_march_optics PRIVATE bakercore)
add_executable(test_march_robust ${BAKER_TEST_DIR}/test_march_robust.c)
target_link_libraries(test_march_robust PRIVATE bakercore)

set(MARCH_CACHE ${CMAKE_CURRENT_BINARY_DIR}/march_kernel_cache)
foreach(path host cl)
  add_test(NAME march_beer_lambert_${path} COMMAND test_march beer_lambert ${path})
  add_test(NAME march_inverse_square_${path} COMMAND test_march inverse_square ${path})
  add_test(NAME march_inverse_square_spot_${path} COMMAND test_march inverse_square_spot ${path})
  add_test(NAME march_energy_${path} COMMAND test_march energy ${path})
  add_test(NAME march_energy_grid_${path} COMMAND test_march energy_grid ${path})
  add_test(NAME march_ball_lens_${path} COMMAND test_march_optics ball_lens ${path})
  add_test(NAME march_grin_${path} COMMAND test_march_optics grin ${path} ${CMAKE_CURRENT_BINARY_DIR})
  add_test(NAME march_precision_${path} COMMAND test_march_robust precision ${path})
  add_test(NAME march_extremes_${path} COMMAND test_march_robust extremes ${path})
  add_test(NAME march_lattice_${path} COMMAND test_march_robust lattice ${path})
endforeach()
add_test(NAME march_straight COMMAND test_march straight)
add_test(NAME march_photons COMMAND test_march photons)
add_test(NAME march_launch_order COMMAND test_march launch_order)
add_test(NAME march_host_vs_device COMMAND test_march_robust host_vs_device)
# 512^3 needs ~9 GiB: skipped (exit 77) when the machine has less available
add_test(NAME march_extremes_512 COMMAND test_march_robust extremes_512)
# About 23 s on 2 cores: labelled slow, still in the default run
# (scripts/test.sh -LE slow leaves it out, -L slow runs it alone).
set_tests_properties(march_extremes_512 PROPERTIES SKIP_RETURN_CODE 77 LABELS slow)

get_property(MARCH_TESTS DIRECTORY PROPERTY TESTS)
list(FILTER MARCH_TESTS INCLUDE REGEX "^march_")
set_tests_properties(${MARCH_TESTS} PROPERTIES
  ENVIRONMENT "BAKER_CACHE_DIR=${MARCH_CACHE}" TIMEOUT 120)
