# Voxelization tests (vox_*): meshes, topology checks and the voxelize stage
# against analytic answers.
add_executable(test_voxelize ${BAKER_TEST_DIR}/test_voxelize.c)
target_link_libraries(test_voxelize PRIVATE bakercore)
add_executable(test_mesh ${BAKER_TEST_DIR}/test_mesh.c)
target_link_libraries(test_mesh PRIVATE bakercore)

set(VOX_TEST_DIR ${CMAKE_BINARY_DIR}/vox_test)
file(MAKE_DIRECTORY ${VOX_TEST_DIR})
foreach(case sphere profile smoothing objects medium scan uniform bricks ties open bad_input)
  add_test(NAME vox_${case} COMMAND test_voxelize ${case} ${VOX_TEST_DIR}/${case})
endforeach()
add_test(NAME vox_bunny COMMAND test_voxelize bunny ${VOX_TEST_DIR}/bunny
         ${CMAKE_SOURCE_DIR}/scenes/meshes/stanford-bunny.obj)
foreach(case io binary check transform)
  add_test(NAME vox_mesh_${case} COMMAND test_mesh ${case} ${VOX_TEST_DIR}/mesh_${case})
endforeach()
