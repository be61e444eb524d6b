include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

# Exactly the libraries that are built and their headers: core, runtime, net and, when built,
# the viewer. The ROS bridges are reached through `gshaptics node` and are not installed (their
# libraries depend on generated DDS types and on roscpp), so neither are their headers.
install(TARGETS ${GSHAPTICS_EXPORTED_TARGETS} EXPORT gshapticsTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
set(_gshaptics_unbuilt_headers PATTERN ros1 EXCLUDE PATTERN ros2 EXCLUDE PATTERN session_ros EXCLUDE)
if(NOT TARGET gshaptics_objects)
  list(APPEND _gshaptics_unbuilt_headers PATTERN objects EXCLUDE PATTERN object_session.h EXCLUDE)
endif()
if(NOT TARGET gshaptics_viewer)
  list(APPEND _gshaptics_unbuilt_headers PATTERN viewer EXCLUDE PATTERN serve_session.h EXCLUDE)
endif()
install(DIRECTORY include/gshaptics DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} ${_gshaptics_unbuilt_headers})
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
install(FILES tools/plot_probe_run.py tools/plot_fidelity.py tools/plot_push.py tools/plot_stability.py tools/plot_stability_traces.py tools/plot_seen_felt.py tools/plot_push_object.py DESTINATION ${CMAKE_INSTALL_DATADIR}/gshaptics)
# The viewer page and its npm packages (gshaptics serve looks in share/gshaptics/web), and the
# DDS configurations.
install(DIRECTORY web/ DESTINATION ${CMAKE_INSTALL_DATADIR}/gshaptics/web
  FILES_MATCHING PATTERN "*.html" PATTERN "*.js" PATTERN "*.css"
  PATTERN "node_modules" EXCLUDE PATTERN "tests" EXCLUDE)
install(DIRECTORY web/node_modules/three web/node_modules/@sparkjsdev
  DESTINATION ${CMAKE_INSTALL_DATADIR}/gshaptics/web/node_modules OPTIONAL)
install(DIRECTORY config/ DESTINATION ${CMAKE_INSTALL_DATADIR}/gshaptics/config)
