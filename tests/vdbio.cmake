# vdbio tests. Included by CMakeLists.txt it defines them; run as a script
# (cmake -DVDB_PRINT=... -DFILE=... -P vdbio.cmake) it is the vdb_print check,
# kept here because every other tests/*.cmake is included as test definitions.
if(CMAKE_SCRIPT_MODE_FILE)
  execute_process(COMMAND ${VDB_PRINT} -l -m ${FILE}
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE errout)
  message("${out}${errout}")
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "vdb_print exited with ${rc} on ${FILE}")
  endif()
  foreach(want "density" "radiance" "creator" "voxel_centering" "fog volume")
    string(FIND "${out}" "${want}" at)
    if(at EQUAL -1)
      message(FATAL_ERROR "vdb_print output lacks \"${want}\"")
    endif()
  endforeach()
  return()
endif()

add_executable(test_vdbio ${BAKER_TEST_DIR}/test_vdbio.c)
target_link_libraries(test_vdbio PRIVATE bakercore)

set(VDBIO_TEST_DIR ${CMAKE_BINARY_DIR}/vdbio_test)
add_test(NAME vdbio_roundtrip COMMAND test_vdbio roundtrip ${VDBIO_TEST_DIR}/roundtrip)
add_test(NAME vdbio_errors COMMAND test_vdbio errors ${VDBIO_TEST_DIR}/errors)
add_test(NAME vdbio_foreign COMMAND test_vdbio foreign ${BAKER_TEST_DIR}/data/vdbio_foreign.vdb)

# The known file, shared by the external readers below.
add_test(NAME vdbio_known_file COMMAND test_vdbio write ${VDBIO_TEST_DIR})
set_tests_properties(vdbio_known_file PROPERTIES FIXTURES_SETUP vdbio_known)

find_program(VDB_PRINT_PROGRAM vdb_print)
if(VDB_PRINT_PROGRAM)
  add_test(NAME vdbio_vdb_print
           COMMAND ${CMAKE_COMMAND} -DVDB_PRINT=${VDB_PRINT_PROGRAM}
                   -DFILE=${VDBIO_TEST_DIR}/known.vdb -P ${BAKER_TEST_DIR}/vdbio.cmake)
  set_tests_properties(vdbio_vdb_print PROPERTIES FIXTURES_REQUIRED vdbio_known)
else()
  message(STATUS "vdb_print not found: test vdbio_vdb_print skipped")
endif()

# pyopenvdb lives in Debian's python3, not in whatever python3 is on PATH.
set(VDBIO_PYTHON /usr/bin/python3 CACHE FILEPATH "a python3 with pyopenvdb")
if(EXISTS ${VDBIO_PYTHON})
  add_test(NAME vdbio_python
           COMMAND ${VDBIO_PYTHON} ${BAKER_TEST_DIR}/vdbio_python_check.py
                   ${VDBIO_TEST_DIR}/known.vdb)
  set_tests_properties(vdbio_python PROPERTIES FIXTURES_REQUIRED vdbio_known)
  # both checksum rules of vdbio.h, implemented again in Python from the text
  add_test(NAME vdbio_checksum_rules
           COMMAND ${VDBIO_PYTHON} ${BAKER_TEST_DIR}/checksum_rules.py $<TARGET_FILE:baker>
                   ${CMAKE_SOURCE_DIR}/scenes ${VDBIO_TEST_DIR}/checksum_rules)
else()
  message(STATUS "${VDBIO_PYTHON} not found: tests vdbio_python, vdbio_checksum_rules skipped")
endif()

# The leaf-by-leaf writer builds the tree tools::copyFromDense builds (issue 15).
add_executable(test_vdbio_tree ${BAKER_TEST_DIR}/test_vdbio_tree.cpp)
target_link_libraries(test_vdbio_tree PRIVATE bakercore)
add_test(NAME vdbio_tree COMMAND test_vdbio_tree ${VDBIO_TEST_DIR})
