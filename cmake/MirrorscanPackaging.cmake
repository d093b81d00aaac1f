# Debian packages with CPack (docs/packages.md), built by scripts/package:
#   mirrorscand  arm64 from the aarch64 preset (the Raspberry Pi boards, rpi5's board.json
#                as /etc/mirrorscan/board.json), amd64 from the host build (the virtual
#                cabinet, for demos and the web page on a PC)
#   mirrorscan   amd64, the host program (host build only)
# The install() rules below exist for these packages: their destinations outside /usr
# (/etc, /lib/systemd, /lib/udev) are absolute, so a plain `cmake --install` would write
# into the running system's /etc; build the packages and install those instead.

set(_packaging_src ${PROJECT_SOURCE_DIR}/cmake/packaging)
set(_packaging_out ${CMAKE_BINARY_DIR}/packaging)
file(MAKE_DIRECTORY ${_packaging_out})

if(MIRRORSCAN_SANITIZE)
  return()  # no packages of sanitizer builds
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(aarch64|arm64)$")
  set(_deb_arch arm64)
  set(_deb_board rpi5)
elseif(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$" AND NOT MIRRORSCAN_FIRMWARE_ONLY)
  set(_deb_arch amd64)
  set(_deb_board virtual)
else()
  message(STATUS "No Debian packages for ${CMAKE_SYSTEM_PROCESSOR} (firmware-only: "
                 "${MIRRORSCAN_FIRMWARE_ONLY}): arm64 boards and the amd64 virtual board only")
  return()
endif()
set(_boards ${PROJECT_SOURCE_DIR}/boards)
set(MIRRORSCAN_DEB_VERSION ${PROJECT_VERSION}-1)

# Directories in the packages are 0755 whatever the umask of whoever builds them.
set(CMAKE_INSTALL_DEFAULT_DIRECTORY_PERMISSIONS
    OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE WORLD_READ WORLD_EXECUTE)

# --- mirrorscand --------------------------------------------------------------------------
install(TARGETS mirrorscand RUNTIME DESTINATION bin COMPONENT mirrorscand)
install(FILES ${_boards}/${_deb_board}/mirrorscand.service
        DESTINATION /lib/systemd/system COMPONENT mirrorscand)
install(FILES ${_packaging_src}/copyright-mirrorscand RENAME copyright
        DESTINATION share/doc/mirrorscand COMPONENT mirrorscand)

if(_deb_arch STREQUAL "arm64")
  # The Pi boards' cameras are libcamera's, loaded from ../lib/mirrorscan beside the
  # daemon (docs/cameras.md).
  install(TARGETS mirrorscan_camera_libcamera LIBRARY DESTINATION lib/mirrorscan
          COMPONENT mirrorscand)
  # The web page is architecture-independent and needs node to bundle, which the
  # firmware-only build does not run: it comes from the host build (scripts/test and
  # scripts/package build that first).
  set(MIRRORSCAN_PREBUILT_WEB_DIR ${PROJECT_SOURCE_DIR}/build/share/mirrorscan/web
      CACHE PATH "The host build's bundled web page, for the arm64 mirrorscand package")
  set(_web_dir ${MIRRORSCAN_PREBUILT_WEB_DIR})
  install(FILES ${_boards}/rpi5/board.json DESTINATION /etc/mirrorscan COMPONENT mirrorscand)
  install(FILES ${_boards}/rpi5/mirrorscan.avahi.service RENAME mirrorscan.service
          DESTINATION /etc/avahi/services COMPONENT mirrorscand)
  foreach(_board rpi4 rpi5)
    install(FILES ${_boards}/${_board}/board.json ${_boards}/${_board}/mirrorscan.avahi.service
            DESTINATION share/mirrorscan/boards/${_board} COMPONENT mirrorscand)
  endforeach()
  install(FILES ${_packaging_src}/60-mirrorscan-gpio.rules
          DESTINATION /lib/udev/rules.d COMPONENT mirrorscand)
  set(MIRRORSCAN_DEB_GROUPS "gpio dialout video")
  set(MIRRORSCAN_DEB_UDEV_GPIO_RULE yes)
  set(_conffiles "/etc/mirrorscan/board.json\n/etc/avahi/services/mirrorscan.service\n")
  # gpiod: the unit's ExecStopPost drives the laser gates low with gpioset.
  set(_daemon_depends "passwd, gpiod")
  set(_daemon_recommends "avahi-daemon")
  set(_daemon_summary "mirror cabinet 3D body scanner daemon (Raspberry Pi boards)")
  set(_daemon_board_text
      "This build is for the Raspberry Pi 5 (/etc/mirrorscan/board.json); the Pi 4's\n"
      "board.json is in /usr/share/mirrorscan/boards/rpi4.")
else()
  set(_web_dir ${MIRRORSCAN_WEB_DIR})
  # The virtual board's board.json with its development token replaced by a token file,
  # which postinst fills at the first install (no token ships in a package), and its
  # scene where the package puts the scenes.
  # Edited as text, so the conffile keeps the layout and key order people know, then
  # checked as JSON.
  file(READ ${_boards}/virtual/board.json _board_json)
  string(REGEX REPLACE "\"token\": *\"[^\"]*\"" "\"token_file\": \"/var/lib/mirrorscan/token\""
         _board_json "${_board_json}")
  string(REGEX REPLACE "\"scene\": *\"([^\"/][^\"]*)\"" "\"scene\": \"/usr/share/mirrorscan/\\1\""
         _board_json "${_board_json}")
  string(JSON _token_file ERROR_VARIABLE _no_token_file GET "${_board_json}" service token_file)
  string(JSON _token ERROR_VARIABLE _no_token GET "${_board_json}" service token)
  string(JSON _scene GET "${_board_json}" virtual scene)
  if(_no_token_file OR NOT _no_token OR NOT _scene MATCHES "^/usr/share/mirrorscan/scenes/")
    message(FATAL_ERROR "boards/virtual/board.json: could not make the packaged board.json "
                        "(service.token -> token_file, virtual.scene -> /usr/share/...)")
  endif()
  file(WRITE ${_packaging_out}/board.json "${_board_json}")
  set_property(DIRECTORY ${PROJECT_SOURCE_DIR} APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS
               ${_boards}/virtual/board.json)
  install(FILES ${_packaging_out}/board.json DESTINATION /etc/mirrorscan COMPONENT mirrorscand)
  install(DIRECTORY ${_boards}/virtual/scenes/ DESTINATION share/mirrorscan/scenes
          COMPONENT mirrorscand)
  set(MIRRORSCAN_DEB_GROUPS "")
  set(MIRRORSCAN_DEB_UDEV_GPIO_RULE no)
  set(_conffiles "/etc/mirrorscan/board.json\n")
  set(_daemon_depends "passwd")
  set(_daemon_recommends "")
  set(_daemon_summary "mirror cabinet 3D body scanner daemon (virtual cabinet)")
  set(_daemon_board_text
      "This build runs the virtual cabinet, a simulated scanner, on a PC: the whole\n"
      "appliance with no hardware, listening on 127.0.0.1:8080.")
endif()
install(DIRECTORY ${_web_dir}/ DESTINATION share/mirrorscan/web COMPONENT mirrorscand)

# Manual pages and changelog.Debian.gz as Debian policy wants them: gzip -9, no name or
# time stamp (-n).
function(_mirrorscan_gzip_9n file)
  execute_process(COMMAND gzip -9nc ${file} OUTPUT_FILE ${file}.gz COMMAND_ERROR_IS_FATAL ANY)
endfunction()
configure_file(${_packaging_src}/mirrorscand.8 ${_packaging_out}/mirrorscand.8 @ONLY)
_mirrorscan_gzip_9n(${_packaging_out}/mirrorscand.8)
install(FILES ${_packaging_out}/mirrorscand.8.gz DESTINATION share/man/man8 COMPONENT mirrorscand)

configure_file(${_packaging_src}/postinst.in ${_packaging_out}/postinst @ONLY)
file(WRITE ${_packaging_out}/conffiles "${_conffiles}")
configure_file(${_packaging_src}/changelog.in ${_packaging_out}/changelog.Debian @ONLY)
_mirrorscan_gzip_9n(${_packaging_out}/changelog.Debian)

# --- mirrorscan (host program) ------------------------------------------------------------
set(_components mirrorscand)
if(_deb_arch STREQUAL "amd64")
  list(APPEND _components mirrorscan)
  install(TARGETS mirrorscan RUNTIME DESTINATION bin COMPONENT mirrorscan)
  install(FILES ${_packaging_src}/copyright-mirrorscan RENAME copyright
          DESTINATION share/doc/mirrorscan COMPONENT mirrorscan)
  configure_file(${_packaging_src}/mirrorscan.1 ${_packaging_out}/mirrorscan.1 @ONLY)
  _mirrorscan_gzip_9n(${_packaging_out}/mirrorscan.1)
  install(FILES ${_packaging_out}/mirrorscan.1.gz DESTINATION share/man/man1 COMPONENT mirrorscan)
endif()
foreach(_component IN LISTS _components)
  install(FILES ${_packaging_out}/changelog.Debian.gz
          DESTINATION share/doc/${_component} COMPONENT ${_component})
endforeach()

# --- CPack --------------------------------------------------------------------------------
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME mirrorscan)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT
    "mirrorscan maintainers <maintainers@users.noreply.h-seed-ce5e0ffd.example>")
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_STRIP_FILES ON)
set(CPACK_COMPONENTS_ALL ${_components})
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_RELEASE 1)
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE ${_deb_arch})
set(CPACK_DEBIAN_PACKAGE_SOURCE mirrorscan)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
# Library dependencies from dpkg-shlibdeps, for the arm64 package against the arm64
# multiarch libraries scripts/setup installs (CPackProjectConfig.cmake says which
# architecture); the explicit Depends are added to them.
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
set(CPACK_DEBIAN_COMPRESSION_TYPE xz)
configure_file(${_packaging_src}/CPackProjectConfig.cmake.in
               ${_packaging_out}/CPackProjectConfig.cmake @ONLY)
set(CPACK_PROJECT_CONFIG_FILE ${_packaging_out}/CPackProjectConfig.cmake)

set(CPACK_DEBIAN_MIRRORSCAND_PACKAGE_NAME mirrorscand)
set(CPACK_DEBIAN_MIRRORSCAND_PACKAGE_DEPENDS "${_daemon_depends}")
set(CPACK_DEBIAN_MIRRORSCAND_PACKAGE_RECOMMENDS "${_daemon_recommends}")
set(CPACK_DEBIAN_MIRRORSCAND_PACKAGE_CONTROL_EXTRA
    "${_packaging_out}/postinst;${_packaging_src}/prerm;${_packaging_src}/postrm;${_packaging_out}/conffiles")
string(CONCAT CPACK_COMPONENT_MIRRORSCAND_DESCRIPTION "${_daemon_summary}\n"
       "mirrorscand runs a mirror cabinet body scanner: it homes the slide, sweeps the\n"
       "line lasers past the subject, reduces every camera frame to laser peaks, stores\n"
       "the scans and serves them, a web page and a device API over HTTP. It runs as\n"
       "the mirrorscan system user under systemd (Type=notify with a watchdog); the\n"
       "API token is made at the first install in /var/lib/mirrorscan/token.\n"
       ${_daemon_board_text})

set(CPACK_DEBIAN_MIRRORSCAN_PACKAGE_NAME mirrorscan)
string(CONCAT CPACK_COMPONENT_MIRRORSCAN_DESCRIPTION
       "mirror cabinet 3D body scanner host program\n"
       "mirrorscan talks to a mirrorscand device (scans, calibration, results) and does\n"
       "everything that is not time-critical on a PC: calibrating the camera and the\n"
       "mirrors, reconstructing point clouds from the laser peaks, Poisson meshes and\n"
       "body measurements. It also renders the virtual cabinet offline.")

include(CPack)

# The packages' test (tests/packages_test.sh): builds them with scripts/package from this
# build, checks their files, installs them into a scratch root with their maintainer
# scripts and runs lintian. A shell script, so the aarch64 preset runs it on the build
# machine (CMAKE_CROSSCOMPILING_EMULATOR only wraps executable targets).
add_test(NAME packages_test
         COMMAND bash ${PROJECT_SOURCE_DIR}/tests/packages_test.sh ${CMAKE_BINARY_DIR} ${_deb_arch})
set_tests_properties(packages_test PROPERTIES TIMEOUT 600 LABELS packages COST 30)
