# Install and Debian package (docs/install.md). Included last by the top-level
# CMakeLists.txt, when every target exists.
#
#   cmake --install BUILD --prefix P   P/bin: the user-facing tools below;
#                                      P/share/hemm: configs/ (with the demo
#                                      key), scenes/, meshes/;
#                                      P/share/doc/hemm: README.md, docs/
#   cd BUILD && cpack -G DEB           hemm_<version>_<arch>.deb (prefix /usr)
#
# User-facing tools: the two stations (hemm-robot, hemm-operator: record,
# replay, --export-mcap), hemm-relay (network impairment between the stations:
# delay, loss, outages; a user tries a setup with it before a real network),
# hemm-truth (SIMULATION ONLY: a run's forces against the scene's exact
# geometry), hemm-vps (VPS scenes, caches and the engine report). Left out:
# tests, benchmarks, fuzzers and hemm-bimanual-workspace (the SIMULATED
# bimanual device's reachability study behind one README figure).
include(GNUInstallDirs)
set(_hemm_tools hemm-robot hemm-operator hemm-relay hemm-truth hemm-vps)
set(_hemm_installed)
foreach(t IN LISTS _hemm_tools)
  if(TARGET ${t})
    list(APPEND _hemm_installed ${t})
  endif()
endforeach()
install(TARGETS ${_hemm_installed} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# The install test runs --help of each of these (tests/install).
set(HEMM_INSTALLED_TOOLS ${_hemm_installed} CACHE INTERNAL "binaries cmake --install puts in bin/")

set(_hemm_data ${CMAKE_INSTALL_DATADIR}/hemm)
# Scenes and the demo key as they are; paths inside a config are relative to
# the config file, and share/hemm keeps deploy/'s layout (configs/ beside
# scenes/), so "../scenes/home.xml" and "demo.key" resolve in both.
install(DIRECTORY ${CMAKE_SOURCE_DIR}/deploy/scenes/ DESTINATION ${_hemm_data}/scenes
        FILES_MATCHING PATTERN "*.xml" PATTERN "README.md")
# The demo key: public, accepted only on a loopback address by both stations;
# readable by everyone (the stations do not warn about the demo key's mode).
install(FILES ${CMAKE_SOURCE_DIR}/deploy/configs/demo.key DESTINATION ${_hemm_data}/configs)
# The VPS configs point at meshes made in the source tree's out/vps
# (deploy/vps/make_scenes.sh); installed, they point at share/hemm/meshes/.
# The installed copies are made in <build>/install-configs (not in
# <build>/share/hemm, which a build-tree run would take for an installed tree).
file(GLOB _hemm_configs ${CMAKE_SOURCE_DIR}/deploy/configs/*.pbtxt)
foreach(c IN LISTS _hemm_configs)
  get_filename_component(_name ${c} NAME)
  file(READ ${c} _text)
  string(REPLACE "\"../../out/vps/" "\"../meshes/" _text "${_text}")
  file(CONFIGURE OUTPUT ${CMAKE_BINARY_DIR}/install-configs/${_name} CONTENT "${_text}" @ONLY)
  install(FILES ${CMAKE_BINARY_DIR}/install-configs/${_name} DESTINATION ${_hemm_data}/configs)
endforeach()
set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${_hemm_configs})
# The meshes of the bimanual paper's two VPS scenes (peg-in-hole: 256
# triangles; assembly: 1.07 M, 53 MB of STL), written at install time by the
# hemm-vps just built (1.6 s), not kept in the repository. hemm-operator
# writes its .vps caches beside them when it can; where it cannot (a
# read-only /usr/share) it builds them in memory on each start.
if(TARGET hemm-vps)
  install(CODE "
    set(_meshes \"\$ENV{DESTDIR}\${CMAKE_INSTALL_PREFIX}/${_hemm_data}/meshes\")
    foreach(_scene peg-in-hole assembly)
      message(STATUS \"Writing: \${_meshes}/\${_scene}-*.stl (hemm-vps scene)\")
      execute_process(COMMAND \"$<TARGET_FILE:hemm-vps>\" scene --name \${_scene} --out \"\${_meshes}\"
                      RESULT_VARIABLE _rc OUTPUT_QUIET)
      if(NOT _rc EQUAL 0)
        message(FATAL_ERROR \"hemm-vps scene --name \${_scene} failed (\${_rc})\")
      endif()
    endforeach()")
endif()

# The documentation a user reads: README and docs/ (with its plots) in
# share/doc/hemm, where Debian keeps a package's documentation.
install(FILES ${CMAKE_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(DIRECTORY ${CMAKE_SOURCE_DIR}/docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR}/docs
        FILES_MATCHING PATTERN "*.md" PATTERN "*.png" PATTERN "data" EXCLUDE)  # data/: a plot's CSVs

# ---------------------------------------------------------------- Debian package
# Depends: computed by dpkg-shlibdeps from the installed binaries' shared
# libraries (the Debian 12 runtime packages: libprotobuf32, libmujoco2.2.2,
# libpcl-*, libsodium23, ...), never written by hand.
set(CPACK_PACKAGE_NAME hemm)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_VENDOR "hemm")
set(CPACK_PACKAGE_CONTACT "hemm maintainers <hemm@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "haptic teleoperation of a mobile manipulator (HEMM) with VPS haptic rendering")
set(CPACK_PACKAGE_DESCRIPTION
    "hemm lets a person feel a remote place through a robot: a robot station streams range scans, depth \
frames and its state over an authenticated link; an operator station renders forces at 1 kHz from a local \
model built from them (virtual proxy on 2D scans, Voxmap-PointShell on meshes and live voxmaps). The robot, \
the haptic devices and the human hands are SIMULATED (MuJoCo, scripted hands). Installs hemm-robot, \
hemm-operator, hemm-relay, hemm-truth and hemm-vps, with the default configs, scenes, meshes and the public \
demo key in /usr/share/hemm.")
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION science)
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# The package's binaries without their debug line tables (the build tree keeps them).
set(CPACK_STRIP_FILES ON)
include(CPack)
