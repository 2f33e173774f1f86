# `cmake --install build --prefix P` (docs/install.md): headers (P/include/rtslam/..., by rtslam_add_module), static
# libraries (P/lib), the rtslam CLI (P/bin), the YAML presets (P/share/rtslam/config), the docs
# (P/share/doc/rtslam) and a CMake package: `find_package(rtslam)` imports rtslam::<module> for every module and
# rtslam::rtslam (all of them). The viewer's page is compiled into rtslam::viz (viz/assets.hpp): nothing to install.
include(CMakePackageConfigHelpers)

set(RTSLAM_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/rtslam)

install(DIRECTORY ${PROJECT_SOURCE_DIR}/config/ DESTINATION ${CMAKE_INSTALL_DATADIR}/rtslam/config)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/docs/ DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(FILES ${PROJECT_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/examples/ DESTINATION ${CMAKE_INSTALL_DOCDIR}/examples)

# rtslam::io reads ROS bags through rtslam::ros_bag (cmake/RtslamRos.cmake) in builds with ROS: a static library's
# private dependencies are part of its link interface, so that target is exported too (absolute ROS paths: the
# installed package is for the machine it was built on, or one with the same ROS packages).
if(RTSLAM_HAVE_ROS)
  set_target_properties(rtslam_ros_bag_deps PROPERTIES EXPORT_NAME ros_bag)
  install(TARGETS rtslam_ros_bag_deps EXPORT rtslamTargets)
endif()

install(EXPORT rtslamTargets NAMESPACE rtslam:: DESTINATION ${RTSLAM_INSTALL_CMAKEDIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/rtslamConfig.cmake.in
  ${PROJECT_BINARY_DIR}/rtslamConfig.cmake INSTALL_DESTINATION ${RTSLAM_INSTALL_CMAKEDIR})
# 0.x: the API may change between minor versions, so a request for 0.1 accepts 0.1.* only.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/rtslamConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/rtslamConfig.cmake ${PROJECT_BINARY_DIR}/rtslamConfigVersion.cmake
  DESTINATION ${RTSLAM_INSTALL_CMAKEDIR})
