# The layering rule "host/ includes nothing from boards/, except the sim command": the
# product (calibration, reconstruction, meshing, measurement, the client and the CLI)
# must not depend on the simulator. Tests (*_test.cc) and the test support listed below
# take their truth from the virtual cabinet and may.
#
# Run by ctest (host_layering, host/CMakeLists.txt):
#   cmake -DSOURCE_DIR=<source tree> -DLINKS_FILE=<build>/host_links.txt -P CheckHostLayering.cmake
# LINKS_FILE lists every host target as "target|folder|test or product|libraries"
# (mirrorscan_write_target_links), written at configure time; tests are not checked.
# Fails with one line per offence.

cmake_minimum_required(VERSION 3.25)

set(_allowed_sources
    host/cli/sim_command.cc  # `mirrorscan sim`: the virtual cabinet offline
    host/meshing/test_clouds.h host/meshing/test_clouds.cc  # test support (meshing tests)
    host/reconstruction/test_sweep.h host/reconstruction/test_sweep.cc)  # (reconstruction tests)
set(_allowed_targets mirrorscan_cli_sim mirrorscan_meshing_test_clouds
    mirrorscan_reconstruction_test_sweep)

set(_offences "")
file(GLOB_RECURSE _sources RELATIVE ${SOURCE_DIR} ${SOURCE_DIR}/host/*.h ${SOURCE_DIR}/host/*.cc)
foreach(_file IN LISTS _sources)
  if(_file MATCHES "_test\\.cc$" OR _file IN_LIST _allowed_sources)
    continue()
  endif()
  file(STRINGS ${SOURCE_DIR}/${_file} _includes REGEX "^[ \t]*#[ \t]*include[ \t]*[\"<]boards/")
  foreach(_include IN LISTS _includes)
    string(STRIP "${_include}" _include)
    list(APPEND _offences "${_file}: ${_include}")
  endforeach()
endforeach()

if(NOT EXISTS ${LINKS_FILE})
  message(FATAL_ERROR "host layering: ${LINKS_FILE} missing (written when CMake configures host/)")
endif()
file(STRINGS ${LINKS_FILE} _links)
foreach(_line IN LISTS _links)
  string(REGEX MATCH "^([^|]+)\\|[^|]*\\|([^|]+)\\|(.*)$" _ "${_line}")
  set(_target ${CMAKE_MATCH_1})
  set(_kind ${CMAKE_MATCH_2})
  set(_libraries "${CMAKE_MATCH_3}")
  if(_kind STREQUAL "test" OR _target IN_LIST _allowed_targets)
    continue()
  endif()
  string(REGEX MATCHALL "mirrorscan_virtual_[A-Za-z0-9_]+" _virtual "${_libraries}")
  foreach(_library IN LISTS _virtual)
    list(APPEND _offences "target ${_target} links ${_library}")
  endforeach()
endforeach()

if(_offences)
  foreach(_offence IN LISTS _offences)
    message("host layering: ${_offence}: host/ may use boards/ only in the sim command "
            "(host/cli/sim_command.cc) and in tests")
  endforeach()
  list(LENGTH _offences _count)
  message(FATAL_ERROR "host layering: ${_count} offence(s)")
endif()
list(LENGTH _sources _source_count)
list(LENGTH _links _target_count)
message("host layering: ${_source_count} sources and ${_target_count} targets, nothing from boards/ "
        "outside the sim command and tests")
