# The firmware-only build's mirrorscand (the board's) carries nothing of the virtual
# cabinet's simulator (docs/firmware.md): no symbol of boards/virtual (namespace
# mirrorscan::virtual_cabinet: the drive simulator, the renderer, the scene), of Embree or
# OpenCV (the renderer's), and no Modbus server function (only the drive simulator serves
# Modbus; the firmware is a client).
#
# Run by ctest (firmware_no_simulator, firmware/app/CMakeLists.txt, firmware-only builds):
#   cmake -DNM=<nm> -DBINARY=<mirrorscand> -P CheckNoSimulatorSymbols.cmake
# Fails with one line per forbidden symbol (the first 20).

cmake_minimum_required(VERSION 3.25)

set(_forbidden
    "mirrorscan::virtual_cabinet::"
    "(^| )cv::"
    " rtc[A-Z][A-Za-z0-9]*(@|$)"
    " modbus_(tcp_listen|tcp_accept|tcp_pi_listen|mapping_new|mapping_new_start_address|reply|receive)(@|$)")

execute_process(COMMAND ${NM} -C ${BINARY}
                OUTPUT_VARIABLE _symbols ERROR_VARIABLE _error RESULT_VARIABLE _result)
if(NOT _result EQUAL 0)
  message(FATAL_ERROR "no-simulator check: ${NM} -C ${BINARY} failed: ${_error}")
endif()
string(REPLACE ";" "\\;" _symbols "${_symbols}")
string(REPLACE "\n" ";" _lines "${_symbols}")
list(LENGTH _lines _count)

set(_offences "")
foreach(_line IN LISTS _lines)
  foreach(_pattern IN LISTS _forbidden)
    if(_line MATCHES "${_pattern}")
      list(APPEND _offences "${_line}")
      break()
    endif()
  endforeach()
endforeach()

if(_offences)
  list(LENGTH _offences _bad)
  message("no-simulator check: ${BINARY} has ${_bad} simulator symbol(s) of ${_count}; it "
          "must not link boards/virtual (only firmware/board/virtual's linked_simulator.cc "
          "does, in the host build):")
  list(SUBLIST _offences 0 20 _shown)
  foreach(_offence IN LISTS _shown)
    message("  ${_offence}")
  endforeach()
  message(FATAL_ERROR "no-simulator check: ${_bad} forbidden symbol(s)")
endif()
message("no-simulator check: ${BINARY}: ${_count} symbols, none of the simulator "
        "(mirrorscan::virtual_cabinet, cv::, Embree rtc*, a Modbus server)")
