# Viewing pass (baker view): host math, then OpenCL renders checked against
# closed forms, a VDB written by pyopenvdb, and bad input.
add_executable(test_view_math ${BAKER_TEST_DIR}/test_view_math.c)
target_link_libraries(test_view_math PRIVATE bakercore)
foreach(t frames srgb camera march)
  add_test(NAME view_math_${t} COMMAND test_view_math ${t})
endforeach()

add_executable(test_view_render ${BAKER_TEST_DIR}/test_view_render.c)
target_link_libraries(test_view_render PRIVATE bakercore)
set(VIEW_TEST_DIR ${CMAKE_CURRENT_BINARY_DIR}/view_tests)
file(MAKE_DIRECTORY ${VIEW_TEST_DIR})
set(VIEW_TESTS view_cube view_cube_rgb view_sequence view_host_device view_lens view_lens_steps)
add_test(NAME view_cube COMMAND test_view_render cube ${VIEW_TEST_DIR})
add_test(NAME view_cube_rgb COMMAND test_view_render cube_rgb ${VIEW_TEST_DIR})
add_test(NAME view_sequence COMMAND test_view_render sequence ${VIEW_TEST_DIR})
add_test(NAME view_host_device COMMAND test_view_render host_device ${VIEW_TEST_DIR})
add_test(NAME view_lens COMMAND test_view_render lens ${VIEW_TEST_DIR})
add_test(NAME view_lens_steps COMMAND test_view_render lens_steps ${VIEW_TEST_DIR})

# Fog volumes of pyopenvdb's making: voxel size 0.05, a translation that is
# not a multiple of it, a box that starts off the leaf-node grid, grey
# extinction with RGB scattering; then voxel size 0.04 turned 30 degrees about
# z. The C test gets the same arguments. A third file has non-cubic voxels.
set(VIEW_PY_ARGS --voxel 0.05 --translate 0.0123,-0.0371,0.0419 --imin -10 --imax 29
    --radiance 0.8,0.5,0.3 --extinction 1.2 --scattering 0.9,0.6,0.3)
set(VIEW_PY_ROT_ARGS --voxel 0.04 --translate 0.3,-0.2,0.1 --rotate-z 30 --imin 3 --imax 42
    --radiance 0.6,0.6,0.9 --extinction 0.7,1.1,1.6 --scattering 0.5)
add_test(NAME view_pyfile_write
         COMMAND /usr/bin/python3 ${BAKER_TEST_DIR}/view_pyfile.py fog
                 ${VIEW_TEST_DIR}/view_pyfile.vdb ${VIEW_PY_ARGS})
add_test(NAME view_pyfile_rotated_write
         COMMAND /usr/bin/python3 ${BAKER_TEST_DIR}/view_pyfile.py fog
                 ${VIEW_TEST_DIR}/view_pyfile_rotated.vdb ${VIEW_PY_ROT_ARGS})
add_test(NAME view_pyfile_bad_write
         COMMAND sh -c "/usr/bin/python3 ${BAKER_TEST_DIR}/view_pyfile.py bool_radiance ${VIEW_TEST_DIR}/view_pyfile_bool.vdb && /usr/bin/python3 ${BAKER_TEST_DIR}/view_pyfile.py fog ${VIEW_TEST_DIR}/view_pyfile_stretched.vdb --stretch-z 2")
set_tests_properties(view_pyfile_write PROPERTIES FIXTURES_SETUP view_pyfile)
set_tests_properties(view_pyfile_rotated_write PROPERTIES FIXTURES_SETUP view_pyfile_rotated)
set_tests_properties(view_pyfile_bad_write PROPERTIES FIXTURES_SETUP view_pyfile_bad)
add_test(NAME view_pyfile COMMAND test_view_render pyfile ${VIEW_TEST_DIR}/view_pyfile.vdb
                                  ${VIEW_TEST_DIR} view_pyfile ${VIEW_PY_ARGS})
set_tests_properties(view_pyfile PROPERTIES FIXTURES_REQUIRED view_pyfile)
add_test(NAME view_pyfile_rotated COMMAND test_view_render pyfile
                                          ${VIEW_TEST_DIR}/view_pyfile_rotated.vdb ${VIEW_TEST_DIR}
                                          view_pyfile_rotated ${VIEW_PY_ROT_ARGS})
set_tests_properties(view_pyfile_rotated PROPERTIES FIXTURES_REQUIRED view_pyfile_rotated)
list(APPEND VIEW_TESTS view_pyfile view_pyfile_rotated)

foreach(c no_radiance radiance_float look_at_equals_position zero_resolution truncated
          missing_input missing_output_dir bad_frames)
  add_test(NAME view_bad_${c} COMMAND test_view_render bad ${c} ${VIEW_TEST_DIR})
  list(APPEND VIEW_TESTS view_bad_${c})
endforeach()
add_test(NAME view_bad_radiance_bool COMMAND test_view_render bad radiance_bool ${VIEW_TEST_DIR}
                                             ${VIEW_TEST_DIR}/view_pyfile_bool.vdb)
add_test(NAME view_bad_nonuniform_transform
         COMMAND test_view_render bad nonuniform_transform ${VIEW_TEST_DIR}
                 ${VIEW_TEST_DIR}/view_pyfile_stretched.vdb)
set_tests_properties(view_bad_radiance_bool view_bad_nonuniform_transform PROPERTIES
  FIXTURES_REQUIRED view_pyfile_bad)
list(APPEND VIEW_TESTS view_bad_radiance_bool view_bad_nonuniform_transform)
# compiled kernels stay inside the build directory
set_tests_properties(${VIEW_TESTS} PROPERTIES
  ENVIRONMENT "BAKER_CACHE_DIR=${CMAKE_CURRENT_BINARY_DIR}/view_kernel_cache")
