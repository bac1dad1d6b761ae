# Dispersion (objects[].abbe, per-channel ior): the keys, and a prism's
# per-channel deviation against Snell's law on the host C path and on OpenCL.
add_executable(test_dispersion ${BAKER_TEST_DIR}/test_dispersion.c)
target_link_libraries(test_dispersion PRIVATE bakercore)
set(DISPERSION_DIR ${CMAKE_BINARY_DIR}/test_dispersion_files)
file(MAKE_DIRECTORY ${DISPERSION_DIR}/parse ${DISPERSION_DIR}/view ${DISPERSION_DIR}/host ${DISPERSION_DIR}/cl)
add_test(NAME dispersion_parse COMMAND test_dispersion parse ${DISPERSION_DIR}/parse)
add_test(NAME dispersion_view COMMAND test_dispersion view ${DISPERSION_DIR}/view)
foreach(path host cl)
  add_test(NAME dispersion_prism_${path} COMMAND test_dispersion prism ${path} ${DISPERSION_DIR}/${path})
endforeach()
set_tests_properties(dispersion_parse dispersion_view dispersion_prism_host dispersion_prism_cl PROPERTIES
  ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_CURRENT_BINARY_DIR}/march_kernel_cache" TIMEOUT 120)
