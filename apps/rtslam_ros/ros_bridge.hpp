#pragma once
// The rtslam_ros node's connection to ROS: parameters, subscriptions and publications. No ROS type appears here:
// ros_bridge.cpp is the node's only translation unit that includes ROS headers (compiled as C++17, see
// cmake/RtslamRos.cmake), the rest of the node works on io:: measurements and the plain Estimate below.
// Topics, parameters and frames are documented in docs/ros.md.
#include <functional>
#include <memory>
#include <string>

#include "estimate.hpp"
#include "rtslam/core/time.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::ros_node {

/// The node's private parameters (~name), with their defaults.
struct NodeParams {
  std::string config;                           // rtslam run configuration YAML ("": the options' defaults)
  std::string calibration;                      // rig file or EuRoC folder (io::load_rig), required
  int camera = 0;                               // camera of the calibration that image_topic shows
  std::string image_topic = "/cam0/image_raw";  // sensor_msgs/Image
  std::string imu_topic = "/imu0";              // sensor_msgs/Imu, subscribed when the robot is inertial
  std::string world_frame = "world";            // W
  std::string robot_frame = "base_link";        // R: the robot body (the IMU on inertial rigs)
  std::string camera_frame;                     // S of the camera: when set, R -> S is published on /tf too
  int queue_size = 30;                          // images waiting for the filter (the oldest is dropped when full)
  int imu_queue_size = 4000;                    // IMU samples waiting for the filter
  int map_every = 1;                            // publish the map every N processed images (0: never)
  std::string trajectory;                       // TUM trajectory file written at exit ("": none)
};

class RosBridge {
 public:
  /// ros::init (node name "rtslam_ros"; argv's ROS remappings and _param:=value are consumed) and the private
  /// parameters. Throws ConfigError naming the parameter for a missing calibration, a bad value or an unknown ~name.
  RosBridge(int& argc, char** argv);
  ~RosBridge();
  RosBridge(const RosBridge&) = delete;
  RosBridge& operator=(const RosBridge&) = delete;

  const NodeParams& params() const;
  /// Advertises ~odom (nav_msgs/Odometry), ~map (sensor_msgs/PointCloud2) and /tf, then subscribes to image_topic
  /// and, with `with_imu`, imu_topic. The callbacks run on spin()'s thread; `on_bad_image` receives one line for
  /// an image that cannot be converted to 8-bit grey.
  void start(std::function<void(io::ImageFrame)> on_image, std::function<void(const io::ImuSample&)> on_imu,
             std::function<void(const std::string&)> on_bad_image, bool with_imu);
  /// Publishes odometry, TF (world -> robot, and robot -> camera when camera_frame is set) and the map. Thread-safe.
  void publish(const Estimate& estimate);
  /// Runs the callbacks until SIGINT or request_shutdown().
  void spin();
  /// Makes spin() return (any thread).
  void request_shutdown();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rtslam::ros_node
