# The firmware's layering (docs/building.md), checked on its sources and its targets' links:
# 1. Only firmware/board/virtual/ uses boards/ (the simulator): its #includes and its
#    targets' mirrorscan_virtual_* libraries. Tests (*_test.cc, *_benchmark.cc, test
#    helpers) take their truth from the simulator and may.
# 2. A hardware header (<libcamera/...>, <gpiod.h>/<gpiod.hpp>, <modbus.h>/<modbus/...>) and
#    its library (PkgConfig::LIBCAMERA, GPIOD, MODBUS) only in its backend's folder,
#    firmware/hal/<backend>/; never in common/ nor anywhere else in firmware/.
# 3. The firmware's folders include one way, so they have no cycle:
#      hal < hal/<backend> < store < scan < board < board/virtual < service < app
#    a folder includes from its own and earlier ones only, and no backend from another.
#    hal/ itself (the interfaces) includes no backend.
#
# Run by ctest (firmware_layering, firmware/CMakeLists.txt):
#   cmake -DSOURCE_DIR=<source tree> -DLINKS_FILE=<build>/firmware_links.txt
#         -P CheckFirmwareLayering.cmake
# LINKS_FILE lists every firmware target as "target|folder|test or product|libraries"
# (mirrorscan_write_target_links), written at configure time. Fails with one line per offence.

cmake_minimum_required(VERSION 3.25)

set(_layers hal hal/* store scan board board/virtual service app)
set(_order "hal < hal/<backend> < store < scan < board < board/virtual < service < app")
set(_hardware_headers "libcamera/[^>]*" "gpiod\\.hpp?" "modbus\\.h" "modbus/[^>]*")
set(_hardware_backends libcamera gpiod modbus modbus)
set(_hardware_libraries PkgConfig::LIBCAMERA PkgConfig::GPIOD PkgConfig::MODBUS)
set(_hardware_library_backends libcamera gpiod modbus)

# The layer of firmware folder `folder` (firmware/ stripped): its index in _layers, and
# the backend for hal/<backend>/...; -1 for a folder outside the list.
function(_firmware_layer folder out_rank out_backend)
  set(_backend "")
  if(folder MATCHES "^hal/([^/]+)")
    set(_key "hal/*")
    set(_backend ${CMAKE_MATCH_1})
  elseif(folder MATCHES "^board/virtual(/|$)")
    set(_key "board/virtual")
  else()
    string(REGEX MATCH "^[^/]+" _key "${folder}")
  endif()
  list(FIND _layers "${_key}" _rank)
  set(${out_rank} ${_rank} PARENT_SCOPE)
  set(${out_backend} "${_backend}" PARENT_SCOPE)
endfunction()

function(_is_test_source file out)
  if(file MATCHES "(_test\\.cc|_benchmark\\.cc|_test_util\\.h|/test_[^/]*\\.h)$" OR
     file MATCHES "/testdata/")
    set(${out} TRUE PARENT_SCOPE)
  else()
    set(${out} FALSE PARENT_SCOPE)
  endif()
endfunction()

set(_offences "")
file(GLOB_RECURSE _sources RELATIVE ${SOURCE_DIR}
     ${SOURCE_DIR}/firmware/*.h ${SOURCE_DIR}/firmware/*.cc
     ${SOURCE_DIR}/common/*.h ${SOURCE_DIR}/common/*.cc)
foreach(_file IN LISTS _sources)
  _is_test_source(${_file} _test)
  get_filename_component(_dir ${_file} DIRECTORY)
  file(STRINGS ${SOURCE_DIR}/${_file} _includes REGEX "^[ \t]*#[ \t]*include[ \t]*[\"<]")
  foreach(_include IN LISTS _includes)
    string(STRIP "${_include}" _include)
    # Rule 2: hardware headers, tests included.
    set(_index 0)
    foreach(_header IN LISTS _hardware_headers)
      if(_include MATCHES "<${_header}>")
        list(GET _hardware_backends ${_index} _backend)
        if(NOT _dir MATCHES "^firmware/hal/${_backend}(/|$)")
          list(APPEND _offences "${_file}: ${_include}: a hardware header belongs in firmware/hal/${_backend}/ only")
        endif()
      endif()
      math(EXPR _index "${_index} + 1")
    endforeach()
    if(_test OR NOT _file MATCHES "^firmware/")
      continue()
    endif()
    # Rule 1: the simulator.
    if(_include MATCHES "[\"<]boards/" AND NOT _dir MATCHES "^firmware/board/virtual(/|$)")
      list(APPEND _offences "${_file}: ${_include}: only firmware/board/virtual/ (and tests) may use boards/ (the simulator)")
    endif()
    # Rule 3: one-way folders.
    if(_include MATCHES "\"firmware/(.*)/[^/]+\"")
      set(_target_dir ${CMAKE_MATCH_1})
      string(REGEX REPLACE "^firmware/" "" _own_dir "${_dir}")
      _firmware_layer("${_own_dir}" _own_rank _own_backend)
      _firmware_layer("${_target_dir}" _target_rank _target_backend)
      if(_target_rank GREATER _own_rank OR
         (_own_rank EQUAL _target_rank AND NOT _own_backend STREQUAL _target_backend))
        list(APPEND _offences "${_file}: ${_include}: firmware/${_own_dir} may not include firmware/${_target_dir} (the folders go ${_order})")
      endif()
    endif()
  endforeach()
endforeach()

if(NOT EXISTS ${LINKS_FILE})
  message(FATAL_ERROR "firmware layering: ${LINKS_FILE} missing (written when CMake configures "
                      "firmware/)")
endif()
file(STRINGS ${LINKS_FILE} _links)
foreach(_line IN LISTS _links)
  string(REGEX MATCH "^([^|]+)\\|([^|]*)\\|([^|]+)\\|(.*)$" _ "${_line}")
  set(_target ${CMAKE_MATCH_1})
  set(_folder ${CMAKE_MATCH_2})
  set(_kind ${CMAKE_MATCH_3})
  set(_libraries "${CMAKE_MATCH_4}")
  set(_index 0)
  foreach(_library IN LISTS _hardware_libraries)
    list(GET _hardware_library_backends ${_index} _backend)
    if(" ${_libraries} " MATCHES " ${_library} " AND NOT _folder MATCHES "^firmware/hal/${_backend}(/|$)")
      list(APPEND _offences "target ${_target} (${_folder}) links ${_library}: only firmware/hal/${_backend}/ may")
    endif()
    math(EXPR _index "${_index} + 1")
  endforeach()
  if(_kind STREQUAL "test" OR _folder MATCHES "^firmware/board/virtual(/|$)")
    continue()
  endif()
  string(REGEX MATCHALL "mirrorscan_virtual_[A-Za-z0-9_]+" _virtual "${_libraries}")
  foreach(_library IN LISTS _virtual)
    list(APPEND _offences "target ${_target} (${_folder}) links ${_library}: only firmware/board/virtual/ (and tests) may link the simulator")
  endforeach()
endforeach()

if(_offences)
  foreach(_offence IN LISTS _offences)
    message("firmware layering: ${_offence}")
  endforeach()
  list(LENGTH _offences _count)
  message(FATAL_ERROR "firmware layering: ${_count} offence(s)")
endif()
list(LENGTH _sources _source_count)
list(LENGTH _links _target_count)
message("firmware layering: ${_source_count} sources and ${_target_count} targets: boards/ only "
        "in firmware/board/virtual and tests, hardware headers and libraries only in their "
        "hal/<backend>, folders one way (${_order})")
