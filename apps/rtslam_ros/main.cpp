// rtslam_ros: the ROS1 node (docs/ros.md). It subscribes to a camera's images (and the IMU when the configuration's
// robot is inertial), runs the image SLAM pipeline (src/rtslam/pipeline/image_slam.hpp) in its own thread on a
// LiveSource fed by the callbacks, and publishes ~odom (nav_msgs/Odometry), /tf (world -> robot) and ~map
// (sensor_msgs/PointCloud2) after every processed image. It stops on SIGINT (or when the pipeline fails), drains
// the queued measurements, optionally writes the trajectory, and prints a one-line summary.
#include <exception>
#include <iostream>
#include <memory>
#include <thread>

#include <fmt/format.h>

#include "estimate.hpp"
#include "ros_bridge.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/io/live_source.hpp"
#include "rtslam/io/rosbag_source.hpp"
#include "rtslam/io/trajectory_io.hpp"
#include "rtslam/pipeline/image_slam.hpp"

namespace rtslam::ros_node {
namespace {

int run(RosBridge& bridge) {
  const NodeParams& params = bridge.params();
  pipeline::ImageSlamOptions options =
      params.config.empty() ? pipeline::ImageSlamOptions{} : pipeline::load_image_slam_config(params.config);
  options.camera = 0;  // the rig below holds the one camera of image_topic
  options.validate();
  const bool inertial = options.robot == "inertial";

  io::Dataset ds;
  ds.name = "ros";
  ds.kind = "ros";
  ds.path = params.image_topic;
  ds.rig = io::load_rig(params.calibration, {params.camera});
  for (const auto& w : ds.rig.warnings) logger("ros")->warn("{}", w);
  if (inertial && !ds.rig.imu) {
    throw ConfigError(
        fmt::format("{}: the configuration's robot is inertial but the calibration has no IMU", params.calibration));
  }
  io::LiveSource::Options lo;
  lo.image_capacity = static_cast<std::size_t>(params.queue_size);
  lo.imu_capacity = static_cast<std::size_t>(params.imu_queue_size);
  lo.with_imu = inertial;
  lo.log_name = "ros";
  auto source = std::make_unique<io::LiveSource>(lo);
  io::LiveSource& live = *source;
  ds.source = std::move(source);
  const Eigen::Isometry3d T_RS = ds.rig.cameras.front().T_RS;

  bridge.start([&live](io::ImageFrame frame) { live.push_image(std::move(frame)); },
               [&live](const io::ImuSample& s) { live.push_imu(s); },
               [&live](const std::string& message) { live.report_bad_image(message); }, inertial);

  pipeline::ImageSlamResult result;
  std::string failure;
  bool data_error = false;
  std::thread filter([&] {
    try {
      result = pipeline::run_image_slam(ds, options, {}, [&](const pipeline::ImageSlamFrame& frame) {
        const bool with_map = params.map_every > 0 && frame.index % params.map_every == 0;
        bridge.publish(make_estimate(frame, T_RS, with_map));
      });
    } catch (const DataError& e) {
      failure = e.what();
      data_error = true;
    } catch (const std::exception& e) {
      failure = e.what();
    }
    bridge.request_shutdown();
  });
  bridge.spin();
  live.close();
  filter.join();

  if (!params.trajectory.empty() && !result.estimate.poses.empty()) io::write_tum(params.trajectory, result.estimate);
  const io::SourceStats input = live.stats();
  logger("ros")->info("rtslam_ros: {} image(s) processed; input: {}", result.frames.size(), input.summary());
  if (input.images == 0 && input.live_images_before_imu > 0) {
    std::cerr << fmt::format("rtslam_ros: no IMU sample received on {}: {} image(s) dropped waiting for it\n",
                             params.imu_topic, input.live_images_before_imu);
    return 1;
  }
  if (data_error && input.images == 0) {
    // Stopped before the first image: nothing went wrong, there was nothing to do.
    logger("ros")->warn("rtslam_ros: no image received on {}", params.image_topic);
    return 0;
  }
  if (!failure.empty()) {
    std::cerr << "rtslam_ros: " << failure << '\n';
    return 1;
  }
  return 0;
}

}  // namespace
}  // namespace rtslam::ros_node

int main(int argc, char** argv) {
  try {
    rtslam::ros_node::RosBridge bridge(argc, argv);
    return rtslam::ros_node::run(bridge);
  } catch (const rtslam::Error& e) {
    std::cerr << "rtslam_ros: " << e.what() << '\n';
    return 1;
  }
}
