# ROS1 support (docs/ros.md): the `rosbag:` dataset kind in rtslam::io and the `rtslam_ros` node.
#
# RTSLAM_WITH_ROS: AUTO (default: build the ROS parts when the packages are found), ON (fail without them), OFF.
# Sets RTSLAM_HAVE_ROS and, when ON, two imported targets:
#   rtslam::ros_bag   rosbag_storage and the message headers (reading and writing bags, no ROS master involved)
#   rtslam::ros_node  roscpp on top of that (the node and the node test)
# and RTSLAM_ROSMASTER (the rosmaster program, for the node test; may be NOTFOUND).
#
# Found without catkin: Debian's catkin config of rosbag_storage pulls in the ROS 2 pluginlib through ament (which
# fails outside a colcon environment), so headers and libraries are looked up directly. Debian's rosbag/bag.h
# includes that ROS 2 pluginlib, whose headers live one folder deeper (/usr/include/pluginlib/pluginlib/...): those
# folders are added when present. Noetic's generated message headers use std::allocator<void>::rebind, removed in
# C++20: the few translation units that include ROS headers are compiled as C++17 (rtslam_ros_cxx17 below), and no
# ROS type crosses their interfaces.
set(RTSLAM_WITH_ROS AUTO CACHE STRING "ROS1 support: AUTO (when found), ON (required) or OFF")
set_property(CACHE RTSLAM_WITH_ROS PROPERTY STRINGS AUTO ON OFF)
set(RTSLAM_HAVE_ROS OFF)

# Compiles the listed sources of the current directory as C++17 (they include ROS headers; see above).
function(rtslam_ros_cxx17)
  set_source_files_properties(${ARGN} PROPERTIES COMPILE_OPTIONS "-std=c++17")
endfunction()

if(NOT RTSLAM_WITH_ROS STREQUAL "OFF")
  set(_ros_missing "")
  set(_ros_include_dirs "")
  foreach(_header rosbag/bag.h ros/ros.h sensor_msgs/Image.h sensor_msgs/CompressedImage.h sensor_msgs/Imu.h
                  sensor_msgs/PointCloud2.h nav_msgs/Odometry.h tf2_msgs/TFMessage.h)
    string(MAKE_C_IDENTIFIER "RTSLAM_ROS_INC_${_header}" _var)
    find_path(${_var} ${_header})
    if(${_var})
      list(APPEND _ros_include_dirs ${${_var}})
    else()
      list(APPEND _ros_missing ${_header})
    endif()
  endforeach()
  # Debian's ROS 2 pluginlib (and what it includes) for rosbag/bag.h; optional where pluginlib is ROS1's.
  foreach(_pair "pluginlib/class_loader.hpp|pluginlib" "class_loader/multi_library_class_loader.hpp|class_loader"
                "ament_index_cpp/get_resource.hpp|ament_index_cpp" "rcpputils/shared_library.hpp|rcpputils"
                "rcutils/shared_library.h|rcutils")
    string(REPLACE "|" ";" _pair ${_pair})
    list(GET _pair 0 _header)
    list(GET _pair 1 _suffix)
    string(MAKE_C_IDENTIFIER "RTSLAM_ROS_INC_${_header}" _var)
    find_path(${_var} ${_header} PATH_SUFFIXES ${_suffix})
    if(${_var})
      list(APPEND _ros_include_dirs ${${_var}})
    endif()
  endforeach()
  set(_ros_bag_libs "")
  foreach(_lib rosbag_storage roscpp_serialization rostime cpp_common console_bridge)
    find_library(RTSLAM_ROS_LIB_${_lib} ${_lib})
    if(RTSLAM_ROS_LIB_${_lib})
      list(APPEND _ros_bag_libs ${RTSLAM_ROS_LIB_${_lib}})
    else()
      list(APPEND _ros_missing lib${_lib})
    endif()
  endforeach()
  set(_ros_node_libs "")
  foreach(_lib roscpp rosconsole xmlrpcpp)
    find_library(RTSLAM_ROS_LIB_${_lib} ${_lib})
    if(RTSLAM_ROS_LIB_${_lib})
      list(APPEND _ros_node_libs ${RTSLAM_ROS_LIB_${_lib}})
    else()
      list(APPEND _ros_missing lib${_lib})
    endif()
  endforeach()
  find_package(Boost QUIET COMPONENTS system thread)
  if(NOT Boost_FOUND)
    list(APPEND _ros_missing "boost (system, thread)")
  endif()
  list(REMOVE_DUPLICATES _ros_include_dirs)

  if(NOT _ros_missing)
    # The headers must compile (as C++17) and a bag must link: a half-installed ROS is "not found".
    include(CheckCXXSourceCompiles)
    set(CMAKE_REQUIRED_INCLUDES ${_ros_include_dirs})
    set(CMAKE_REQUIRED_LIBRARIES ${_ros_bag_libs})
    set(CMAKE_REQUIRED_FLAGS "-std=c++17")
    set(CMAKE_REQUIRED_QUIET ON)
    check_cxx_source_compiles([[
      #include <rosbag/bag.h>
      #include <rosbag/view.h>
      #include <sensor_msgs/Image.h>
      int main() { rosbag::Bag bag; sensor_msgs::Image image; (void)image; return bag.isOpen() ? 1 : 0; }
    ]] RTSLAM_ROS_BAG_COMPILES)
    unset(CMAKE_REQUIRED_INCLUDES)
    unset(CMAKE_REQUIRED_LIBRARIES)
    unset(CMAKE_REQUIRED_FLAGS)
    unset(CMAKE_REQUIRED_QUIET)
    if(NOT RTSLAM_ROS_BAG_COMPILES)
      list(APPEND _ros_missing "a rosbag test program that compiles and links (see CMakeFiles/CMakeError.log)")
    endif()
  endif()

  if(NOT _ros_missing)
    set(RTSLAM_HAVE_ROS ON)
    add_library(rtslam_ros_bag_deps INTERFACE)
    add_library(rtslam::ros_bag ALIAS rtslam_ros_bag_deps)
    target_include_directories(rtslam_ros_bag_deps SYSTEM INTERFACE ${_ros_include_dirs})
    target_link_libraries(rtslam_ros_bag_deps INTERFACE ${_ros_bag_libs})
    add_library(rtslam_ros_node_deps INTERFACE)
    add_library(rtslam::ros_node ALIAS rtslam_ros_node_deps)
    target_link_libraries(rtslam_ros_node_deps INTERFACE rtslam_ros_bag_deps ${_ros_node_libs} Boost::system
                          Boost::thread)
    find_program(RTSLAM_ROSMASTER rosmaster)
    message(STATUS "ROS1: found (rosbag: dataset kind, rtslam_ros node; rosmaster: ${RTSLAM_ROSMASTER})")
  elseif(RTSLAM_WITH_ROS STREQUAL "ON")
    message(FATAL_ERROR "RTSLAM_WITH_ROS=ON but ROS1 is incomplete; missing: ${_ros_missing} "
                        "(bash scripts/deps.sh installs the Debian packages)")
  else()
    message(STATUS "ROS1: not found (missing: ${_ros_missing}); the rosbag: kind and rtslam_ros are not built")
  endif()
else()
  message(STATUS "ROS1: off (RTSLAM_WITH_ROS=OFF); the rosbag: kind and rtslam_ros are not built")
endif()
