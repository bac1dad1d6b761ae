# Adaptive pipeline (issue 5). test_adaptive: the parts on their own —
# light-domain cells and origin masks, the PDF warp, the PDF from origin
# data, automatic thresholds, the reconstruction filter on the host and on
# OpenCL. test_adaptive_pipeline: ad_bake end to end on the sphere scene
# (64^3) against the reference march — unbiasedness with the filter off,
# quality at half the photons, the error estimate, the filter radius grid, host vs OpenCL, and
# the baker bake command's grids and metadata.
add_executable(test_adaptive ${BAKER_TEST_DIR}/test_adaptive.c)
target_link_libraries(test_adaptive PRIVATE bakercore)
foreach(t cells warp pdf thresholds chain filter filter_cl fixed device)
  add_test(NAME adaptive_${t} COMMAND test_adaptive ${t})
endforeach()

add_executable(test_adaptive_pipeline ${BAKER_TEST_DIR}/test_adaptive_pipeline.c)
target_link_libraries(test_adaptive_pipeline PRIVATE bakercore)
set(ADAPTIVE_OUT ${CMAKE_BINARY_DIR}/adaptive_tests)
file(MAKE_DIRECTORY ${ADAPTIVE_OUT})
foreach(t unbiased lights quality estimate filter_radius host_vs_device cli)
  add_test(NAME adaptive_${t}
           COMMAND test_adaptive_pipeline ${CMAKE_SOURCE_DIR}/scenes ${ADAPTIVE_OUT} ${t})
endforeach()

# The OpenCL tests keep their kernel cache in the build tree, not in ~/.cache.
set_tests_properties(adaptive_filter_cl adaptive_device adaptive_unbiased adaptive_lights
                     adaptive_quality adaptive_estimate
                     adaptive_filter_radius adaptive_host_vs_device adaptive_cli
                     PROPERTIES ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_BINARY_DIR}/adaptive_kernel_cache"
                                TIMEOUT 300)
