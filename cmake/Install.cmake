include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

install(TARGETS gshaptics EXPORT gshapticsTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY include/gshaptics DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(EXPORT gshapticsTargets NAMESPACE gshaptics::
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/gshaptics)
configure_package_config_file(cmake/gshapticsConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/gshapticsConfig.cmake
  INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/gshaptics)
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/gshapticsConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/gshapticsConfig.cmake
  ${CMAKE_CURRENT_BINARY_DIR}/gshapticsConfigVersion.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/gshaptics)
install(FILES tools/plot_probe_run.py DESTINATION ${CMAKE_INSTALL_DATADIR}/gshaptics)
# The viewer page and its npm packages (gshaptics serve looks in share/gshaptics/web), and the
# DDS configurations.
install(FILES web/index.html web/app.js web/style.css DESTINATION ${CMAKE_INSTALL_DATADIR}/gshaptics/web)
install(DIRECTORY web/node_modules/three web/node_modules/@sparkjsdev
  DESTINATION ${CMAKE_INSTALL_DATADIR}/gshaptics/web/node_modules OPTIONAL)
install(DIRECTORY config/ DESTINATION ${CMAKE_INSTALL_DATADIR}/gshaptics/config)
