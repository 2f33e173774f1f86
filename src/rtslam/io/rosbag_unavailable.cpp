// Stand-ins for rosbag_source.cpp in builds without ROS (cmake/RtslamRos.cmake did not find ROS1, or
// RTSLAM_WITH_ROS=OFF): the rosbag: kind and the bag writer say so with a ConfigError.
#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/io/rosbag_source.hpp"

namespace rtslam::io {
namespace {

[[noreturn]] void no_ros(const std::string& path) {
  throw ConfigError(
      fmt::format("{}: this rtslam was built without ROS support (ROS1 packages not found when it was "
                  "configured: install them with scripts/deps.sh and configure again, see docs/ros.md)",
                  path));
}

}  // namespace

bool rosbag_supported() { return false; }

Dataset open_rosbag(const std::string& path, const DatasetOptions& /*options*/) { no_ros(path); }

RosbagWriteStats write_rosbag(Source& /*source*/, const Rig& /*rig*/, const std::string& path,
                              const RosbagWriteOptions& /*options*/) {
  no_ros(path);
}

}  // namespace rtslam::io
