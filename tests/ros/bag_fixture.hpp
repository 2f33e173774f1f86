#pragma once
// Hand-made bags for the reader's edge cases (stamps out of order, NaNs, encodings, wrong types, receive times
// that differ from the header stamps): messages written as given, in the given order. No ROS type appears here;
// bag_fixture.cpp is compiled as C++17 with the ROS headers (cmake/RtslamRos.cmake).
#include <cstdint>
#include <string>
#include <variant>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/time.hpp"

namespace rtslam::ros_test {

/// sensor_msgs/Image.
struct RawImage {
  std::string topic = "/cam0/image_raw";
  TimeNs stamp = 0;    // header stamp
  TimeNs receive = 0;  // the bag's receive time (0: = stamp)
  std::string encoding = "mono8";
  std::uint32_t width = 0, height = 0, step = 0;
  std::vector<std::uint8_t> data;
};

/// sensor_msgs/CompressedImage.
struct RawCompressed {
  std::string topic = "/cam0/image_raw";
  TimeNs stamp = 0;
  TimeNs receive = 0;
  std::string format = "png";
  std::vector<std::uint8_t> data;
};

/// sensor_msgs/Imu.
struct RawImu {
  std::string topic = "/imu0";
  TimeNs stamp = 0;
  TimeNs receive = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
};

using RawMessage = std::variant<RawImage, RawCompressed, RawImu>;

/// Writes the messages into a new bag at `path`, in the given order.
void write_bag(const std::string& path, const std::vector<RawMessage>& messages);

}  // namespace rtslam::ros_test
