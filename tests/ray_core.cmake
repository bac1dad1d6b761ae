# The ray core shared by the photon march and the view (tests/test_ray_core.c),
# and the layering of the code base (tests/check_layout.py).
add_executable(test_ray_core ${BAKER_TEST_DIR}/test_ray_core.c)
target_link_libraries(test_ray_core PRIVATE bakercore)
foreach(t field sampler sparse step atten_slab pyramid cells)
  add_test(NAME ray_core_${t} COMMAND test_ray_core ${t})
endforeach()

find_package(Python3 COMPONENTS Interpreter)
if(Python3_Interpreter_FOUND)
  add_test(NAME layout COMMAND ${Python3_EXECUTABLE} ${BAKER_TEST_DIR}/check_layout.py
                               ${CMAKE_SOURCE_DIR})
endif()
