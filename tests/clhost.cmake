# OpenCL host layer (tests/test_clhost.c), on PoCL.
add_executable(test_clhost ${BAKER_TEST_DIR}/test_clhost.c)
target_link_libraries(test_clhost PRIVATE bakercore)

add_test(NAME clhost_errors COMMAND test_clhost errors)
add_test(NAME clhost_cache COMMAND test_clhost cache ${CMAKE_CURRENT_BINARY_DIR})
add_test(NAME clhost_build_error COMMAND test_clhost build_error)
add_test(NAME clhost_device_spec COMMAND test_clhost device_spec)
# large copies through the pinned stages of a discrete device (PoCL made one)
add_test(NAME clhost_copy COMMAND test_clhost copy)
set_tests_properties(clhost_copy PROPERTIES ENVIRONMENT "BAKER_CL_DISCRETE=1")
# ocl-icd reads ICDs from OCL_ICD_VENDORS when it names a directory: an empty
# one is a machine without any OpenCL platform.
set(CLHOST_EMPTY_ICD_DIR ${CMAKE_CURRENT_BINARY_DIR}/clhost_empty_icd)
file(MAKE_DIRECTORY ${CLHOST_EMPTY_ICD_DIR})
add_test(NAME clhost_no_platform COMMAND test_clhost no_platform)
set_tests_properties(clhost_no_platform PROPERTIES
  ENVIRONMENT "OCL_ICD_VENDORS=${CLHOST_EMPTY_ICD_DIR}")
# The kernel cache of the other tests stays inside the build directory.
set_tests_properties(clhost_build_error clhost_device_spec PROPERTIES
  ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_CURRENT_BINARY_DIR}/clhost_kernel_cache")
