# Installs the firmware component into a fresh prefix and checks that the daemon and the
# libcamera module land where the loader looks for the module: bin/../lib beside the
# running executable (firmware/hal/libcamera/libcamera_loader.cc, docs/cameras.md).
# Run by ctest (firmware_install, firmware/app/CMakeLists.txt):
#   cmake -DBUILD_DIR=<build> -DPREFIX=<dir> -DDAEMON=mirrorscand -DMODULE=<module file>
#         -P CheckFirmwareInstall.cmake
cmake_minimum_required(VERSION 3.25)

file(REMOVE_RECURSE ${PREFIX})
execute_process(
  COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${PREFIX} --component firmware
  RESULT_VARIABLE _result OUTPUT_VARIABLE _output ERROR_VARIABLE _output)
if(NOT _result EQUAL 0)
  message(FATAL_ERROR "firmware install: cmake --install failed (${_result}):\n${_output}")
endif()
message("${_output}")

set(_daemon ${PREFIX}/bin/${DAEMON})
# What the loader computes from the daemon's path: its directory's parent, then lib/.
get_filename_component(_bin ${_daemon} DIRECTORY)
get_filename_component(_root ${_bin} DIRECTORY)
set(_module ${_root}/lib/${MODULE})
set(_missing "")
foreach(_file ${_daemon} ${_module})
  if(NOT EXISTS ${_file})
    list(APPEND _missing ${_file})
  endif()
endforeach()
if(_missing)
  message(FATAL_ERROR "firmware install: missing ${_missing} (the loader looks for the module "
                      "in bin/../lib beside mirrorscand)")
endif()
message("firmware install: ${_daemon} and ${_module}, where the loader looks")
file(REMOVE_RECURSE ${PREFIX})
