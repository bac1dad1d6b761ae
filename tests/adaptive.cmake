# Adaptive pipeline (issue 5): the parts around the march — light-domain
# cells and origin masks, the PDF warp, the PDF from origin data, automatic
# thresholds, and the reconstruction filter on the host and on OpenCL.
add_executable(test_adaptive ${BAKER_TEST_DIR}/test_adaptive.c)
target_link_libraries(test_adaptive PRIVATE bakercore)
foreach(t cells warp pdf thresholds chain filter filter_cl device)
  add_test(NAME adaptive_${t} COMMAND test_adaptive ${t})
endforeach()
# The OpenCL tests keep their kernel cache in the build tree, not in ~/.cache.
set_tests_properties(adaptive_filter_cl adaptive_device PROPERTIES
                     ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_BINARY_DIR}/adaptive_kernel_cache")
