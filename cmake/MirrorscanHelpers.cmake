# One library per module, tests and benchmarks beside their code (as COLMAP does).
#
#   mirrorscan_add_library(NAME geometry SRCS camera.cc ... DEPS Eigen3::Eigen)
#   mirrorscan_add_test(NAME geometry_test SRCS camera_test.cc DEPS geometry)
#   mirrorscan_add_executable(NAME mirrorscan SRCS main.cc DEPS ...)
#   mirrorscan_add_benchmark(NAME render_benchmark SRCS render_benchmark.cc DEPS ...)
# Libraries are named mirrorscan_<NAME>; include paths are rooted at the source tree so
# every include reads "common/geometry/camera.h".

set(MIRRORSCAN_WARNINGS -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
    -Wcast-align -Woverloaded-virtual -Wnull-dereference -Wimplicit-fallthrough)

function(_mirrorscan_common target)
  target_include_directories(${target} PUBLIC ${PROJECT_SOURCE_DIR})
  target_compile_options(${target} PRIVATE ${MIRRORSCAN_WARNINGS})
endfunction()

function(mirrorscan_add_library)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(mirrorscan_${ARG_NAME} STATIC ${ARG_SRCS})
  _mirrorscan_common(mirrorscan_${ARG_NAME})
  target_link_libraries(mirrorscan_${ARG_NAME} PUBLIC ${ARG_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
endfunction()

function(mirrorscan_add_executable)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;DEPS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SRCS})
  _mirrorscan_common(${ARG_NAME})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS})
endfunction()

# ONE_PROCESS: ctest runs the binary once, as one test named NAME, instead of a process per
# test case; for suites whose cases share an expensive setup (a static table, a
# SetUpTestSuite) that a process per case would redo. COST (seconds, about) lets ctest start
# such a long test first on a clean build, where it has no timings yet.
function(mirrorscan_add_test)
  cmake_parse_arguments(ARG "ONE_PROCESS" "NAME;TIMEOUT;COST" "SRCS;DEPS;LABELS;FIXTURES" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SRCS})
  _mirrorscan_common(${ARG_NAME})
  # Tests may use what product code may not (cmake/CheckHostLayering.cmake).
  set_target_properties(${ARG_NAME} PROPERTIES MIRRORSCAN_TEST ON)
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  target_compile_definitions(${ARG_NAME} PRIVATE
      MIRRORSCAN_SOURCE_DIR="${PROJECT_SOURCE_DIR}")
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 600)
  endif()
  # FIXTURES: ctest fixtures the tests need set up first (e.g. cabinet_lens, tests/).
  set(_properties TIMEOUT ${ARG_TIMEOUT})
  if(ARG_LABELS)
    list(APPEND _properties LABELS "${ARG_LABELS}")
  endif()
  if(ARG_FIXTURES)
    list(APPEND _properties FIXTURES_REQUIRED "${ARG_FIXTURES}")
    target_compile_definitions(${ARG_NAME} PRIVATE
        MIRRORSCAN_TEST_DATA_DIR="${CMAKE_BINARY_DIR}/test-data")
  endif()
  if(ARG_COST)
    list(APPEND _properties COST ${ARG_COST})
  endif()
  if(ARG_ONE_PROCESS)
    add_test(NAME ${ARG_NAME} COMMAND ${ARG_NAME})
    set_tests_properties(${ARG_NAME} PROPERTIES ${_properties})
  else()
    # PRE_TEST: discovery runs at ctest time, so the cross build discovers under qemu.
    gtest_discover_tests(${ARG_NAME} DISCOVERY_MODE PRE_TEST DISCOVERY_TIMEOUT 120
        PROPERTIES ${_properties})
  endif()
endfunction()

function(mirrorscan_add_benchmark)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;DEPS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SRCS})
  _mirrorscan_common(${ARG_NAME})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS} benchmark::benchmark
      benchmark::benchmark_main)
endfunction()

# A shared library loaded at run time with dlopen (lib<NAME>.so in build/lib/mirrorscan,
# as installed: /usr/lib/mirrorscan, a private directory since it has no SONAME). It exports
# only what is marked __attribute__((visibility("default"))); the static mirrorscan
# libraries it links stay private to it (--exclude-libs) and must be built with
# POSITION_INDEPENDENT_CODE.
function(mirrorscan_add_module)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;DEPS" ${ARGN})
  add_library(${ARG_NAME} MODULE ${ARG_SRCS})
  _mirrorscan_common(${ARG_NAME})
  set_target_properties(${ARG_NAME} PROPERTIES
      CXX_VISIBILITY_PRESET hidden VISIBILITY_INLINES_HIDDEN ON
      LIBRARY_OUTPUT_DIRECTORY ${CMAKE_BINARY_DIR}/lib/mirrorscan)
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS})
  target_link_options(${ARG_NAME} PRIVATE -Wl,--exclude-libs,ALL -Wl,--no-undefined)
endfunction()

# Every target defined in `dir` and below.
function(mirrorscan_targets_under dir out)
  get_property(_targets DIRECTORY ${dir} PROPERTY BUILDSYSTEM_TARGETS)
  get_property(_subdirs DIRECTORY ${dir} PROPERTY SUBDIRECTORIES)
  foreach(_subdir IN LISTS _subdirs)
    mirrorscan_targets_under(${_subdir} _more)
    list(APPEND _targets ${_more})
  endforeach()
  set(${out} ${_targets} PARENT_SCOPE)
endfunction()

# Writes `file`: one line per target defined in `dir` and below,
# "target|folder|test or product|link libraries" (the folder relative to the source tree,
# the libraries space-separated), for the layering checks (cmake/Check*Layering.cmake).
function(mirrorscan_write_target_links dir file)
  mirrorscan_targets_under(${dir} _targets)
  set(_text "")
  foreach(_target IN LISTS _targets)
    get_target_property(_is_test ${_target} MIRRORSCAN_TEST)
    get_target_property(_folder ${_target} SOURCE_DIR)
    file(RELATIVE_PATH _folder ${PROJECT_SOURCE_DIR} ${_folder})
    set(_libraries "")
    foreach(_property LINK_LIBRARIES INTERFACE_LINK_LIBRARIES)
      get_target_property(_values ${_target} ${_property})
      if(_values)
        list(APPEND _libraries ${_values})
      endif()
    endforeach()
    list(REMOVE_DUPLICATES _libraries)
    list(JOIN _libraries " " _libraries)
    if(_is_test)
      set(_kind test)
    else()
      set(_kind product)
    endif()
    string(APPEND _text "${_target}|${_folder}|${_kind}|${_libraries}\n")
  endforeach()
  file(WRITE ${file} "${_text}")
endfunction()
