# What other tools read (issue 13): NanoVDB output and validation, and the
# Blender add-on rendered with Cycles against `baker view`.
find_program(NANOVDB_VALIDATE_PROGRAM nanovdb_validate)
find_program(NANOVDB_CONVERT_PROGRAM nanovdb_convert)
if(NANOVDB_VALIDATE_PROGRAM AND NANOVDB_CONVERT_PROGRAM)
  add_test(NAME interop_nanovdb
           COMMAND bash ${BAKER_TEST_DIR}/nanovdb_check.sh $<TARGET_FILE:baker>
                   $<TARGET_FILE:bench_tool> ${CMAKE_BINARY_DIR}/interop_nanovdb
                   ${CMAKE_SOURCE_DIR}/scenes)
else()
  message(STATUS "nanovdb_validate/nanovdb_convert not found (libnanovdb-tools): "
                 "test interop_nanovdb skipped")
endif()

# Blender (bpy 5.0.1 in a venv cached in the build directory; the first run
# downloads it). Skipped, with the reason, where bpy cannot be installed.
add_test(NAME interop_blender
         COMMAND bash ${BAKER_TEST_DIR}/blender_check.sh $<TARGET_FILE:baker>
                 ${CMAKE_SOURCE_DIR}/scenes ${CMAKE_BINARY_DIR}/interop_blender
                 ${CMAKE_SOURCE_DIR} ${CMAKE_BINARY_DIR}/bpy-venv)
set_tests_properties(interop_blender PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 900)
