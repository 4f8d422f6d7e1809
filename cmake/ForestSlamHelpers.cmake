# forest_slam_library(<module> SOURCES ... PUBLIC_DEPS ... PRIVATE_DEPS ...)
# Creates target forest_slam_<module> (alias forest_slam::<module>) with headers
# in libs/<module>/include/forest_slam/<module>/.
function(forest_slam_library module)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  set(target forest_slam_${module})
  add_library(${target} STATIC ${ARG_SOURCES})
  add_library(forest_slam::${module} ALIAS ${target})
  target_include_directories(${target} PUBLIC
    ${CMAKE_CURRENT_SOURCE_DIR}/include)
  target_link_libraries(${target} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
endfunction()

# forest_slam_app(<name> SOURCES ... DEPS ...): an executable in build/bin.
function(forest_slam_app name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS})
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/bin)
endfunction()

# forest_slam_gtest(<name> SOURCES ... DEPS ... [LABELS ...]): a GoogleTest
# binary registered with ctest; tests run from the repository root so that
# ../shared/data and ini/ resolve as documented.
function(forest_slam_gtest name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;DEPS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE
    FOREST_SLAM_SOURCE_DIR="${FOREST_SLAM_SOURCE_DIR}"
    FOREST_SLAM_SHARED_DIR="${FOREST_SLAM_SHARED_DIR}"
    FOREST_SLAM_BIN_DIR="${CMAKE_BINARY_DIR}/bin")
  set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/tests)
  add_test(NAME ${name} COMMAND ${name} WORKING_DIRECTORY ${FOREST_SLAM_SOURCE_DIR})
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 300)
  endif()
  # Sanitizer builds run the end-to-end tests 5-10x slower (make test-asan).
  if(FOREST_SLAM_SANITIZE)
    math(EXPR ARG_TIMEOUT "${ARG_TIMEOUT} * 10")
  endif()
  # Scratch files of the tests go under the build tree (TMPDIR is what
  # std::filesystem::temp_directory_path() reads), not into the machine's
  # /tmp where every run used to leave its fs_* folders behind.
  file(MAKE_DIRECTORY ${CMAKE_BINARY_DIR}/test-tmp)
  set_tests_properties(${name} PROPERTIES TIMEOUT ${ARG_TIMEOUT}
    ENVIRONMENT "TMPDIR=${CMAKE_BINARY_DIR}/test-tmp")
  if(ARG_LABELS)
    set_tests_properties(${name} PROPERTIES LABELS "${ARG_LABELS}")
  endif()
endfunction()

macro(forest_slam_find_pcl)
  if(NOT PCL_FOUND)
    # VTK (pulled by PCL's config) needs MPI::MPI_C to exist.
    find_package(MPI COMPONENTS C QUIET)
    find_package(PCL 1.12 REQUIRED COMPONENTS common kdtree search filters sample_consensus segmentation registration io)
  endif()
endmacro()
