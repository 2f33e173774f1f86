#pragma once
// A ROS node inside the node test: publishes measurements on the rtslam_ros node's input topics and records what it
// publishes. No ROS type appears here: ros_client.cpp is compiled as C++17 with the ROS headers
// (cmake/RtslamRos.cmake). The master is the one of ROS_MASTER_URI in the environment when the client is created;
// it must be up (roscpp waits for it without a time limit).
#include <array>
#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "rtslam/core/time.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::ros_test {

struct ReceivedOdometry {
  TimeNs t = 0;
  std::string frame_id;
  std::string child_frame_id;
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  std::array<double, 36> pose_covariance{};
};

struct ReceivedTransform {
  TimeNs t = 0;
  std::string parent;
  std::string child;
};

class RosTestClient {
 public:
  /// ros::init (once per process; no SIGINT handler) and a node named `name`, its callbacks on a spinner thread.
  RosTestClient(const std::string& name, const std::string& image_topic, const std::string& imu_topic,
                const std::string& odom_topic, const std::string& map_topic);
  ~RosTestClient();
  RosTestClient(const RosTestClient&) = delete;
  RosTestClient& operator=(const RosTestClient&) = delete;

  /// True once the image topic (and, with `imu`, the IMU topic) has `n` subscribers (polls until `timeout_s`).
  bool wait_for_subscribers(std::size_t n, bool imu, double timeout_s);
  /// True once the odometry, map and /tf subscriptions are connected to `n` publishers each (polls until
  /// `timeout_s`): what a node publishes before that is lost (ROS does not keep messages for later subscribers).
  bool wait_for_publishers(std::size_t n, double timeout_s);
  /// Forgets what was received.
  void clear();
  /// Publishes an image (mono8) or an IMU sample.
  void publish(const io::Measurement& m);
  /// True once `n` odometry messages arrived (polls until `timeout_s`).
  bool wait_for_odometry(std::size_t n, double timeout_s);

  std::vector<ReceivedOdometry> odometry() const;
  std::vector<ReceivedTransform> transforms() const;
  std::size_t map_messages() const;
  std::size_t last_map_points() const;
  std::vector<std::string> last_map_fields() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rtslam::ros_test
