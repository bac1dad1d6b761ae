# Bakes the bundled armadillo scene (issue 2) and checks the file the way
# users' tools read it: vdb_print, and OpenVDB's Python module sampling `ior`
# at points an independent winding-number test places inside and outside.
add_test(NAME example_armadillo_bake
         COMMAND $<TARGET_FILE:baker> bake ${CMAKE_SOURCE_DIR}/scenes/armadillo.json
                 -o ${CMAKE_BINARY_DIR}/example/armadillo.vdb --force --photons 20000)
add_test(NAME example_armadillo_check
         COMMAND /usr/bin/python3 ${BAKER_TEST_DIR}/armadillo_check.py
                 ${CMAKE_BINARY_DIR}/example/armadillo.vdb
                 ${CMAKE_SOURCE_DIR}/scenes/meshes/armadillo.obj 0.01 180 0 -0.215 0 1.5 1.0)
set_tests_properties(example_armadillo_bake PROPERTIES FIXTURES_SETUP armadillo_vdb)
set_tests_properties(example_armadillo_check PROPERTIES FIXTURES_REQUIRED armadillo_vdb)
file(MAKE_DIRECTORY ${CMAKE_BINARY_DIR}/example)
