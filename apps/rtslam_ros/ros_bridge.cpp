// The only translation unit of rtslam_ros that includes ROS headers (compiled as C++17: Noetic's generated
// messages use std::allocator<void>::rebind, removed in C++20).
#include "ros_bridge.hpp"

#include <cstring>
#include <set>

#include <fmt/format.h>
#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/io/rosbag_source.hpp"
#include "rtslam/io/text.hpp"

namespace rtslam::ros_node {
namespace {

TimeNs to_ns(const ros::Time& t) { return static_cast<TimeNs>(t.sec) * kNsPerSecond + static_cast<TimeNs>(t.nsec); }

ros::Time to_ros_time(TimeNs t) {
  if (t < 0) t = 0;
  return ros::Time(static_cast<std::uint32_t>(t / kNsPerSecond), static_cast<std::uint32_t>(t % kNsPerSecond));
}

/// Reads ~name into `value` when it is set; ConfigError when it has another type.
template <class T>
void read_param(const ros::NodeHandle& pnh, const std::string& name, T& value, const char* type) {
  if (pnh.hasParam(name) && !pnh.getParam(name, value)) {
    throw ConfigError(fmt::format("parameter {}/{} must be {}", pnh.getNamespace(), name, type));
  }
}

geometry_msgs::TransformStamped transform(const ros::Time& stamp, const std::string& parent, const std::string& child,
                                          const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
  geometry_msgs::TransformStamped T;
  T.header.stamp = stamp;
  T.header.frame_id = parent;
  T.child_frame_id = child;
  T.transform.translation.x = p.x();
  T.transform.translation.y = p.y();
  T.transform.translation.z = p.z();
  T.transform.rotation.w = q.w();
  T.transform.rotation.x = q.x();
  T.transform.rotation.y = q.y();
  T.transform.rotation.z = q.z();
  return T;
}

}  // namespace

struct RosBridge::Impl {
  NodeParams params;
  std::unique_ptr<ros::NodeHandle> nh;
  std::unique_ptr<ros::NodeHandle> pnh;
  ros::Subscriber image_sub;
  ros::Subscriber imu_sub;
  ros::Publisher odom_pub;
  ros::Publisher map_pub;
  ros::Publisher tf_pub;
};

RosBridge::RosBridge(int& argc, char** argv) : impl_(std::make_unique<Impl>()) {
  ros::init(argc, argv, "rtslam_ros");
  impl_->nh = std::make_unique<ros::NodeHandle>();
  impl_->pnh = std::make_unique<ros::NodeHandle>("~");
  const ros::NodeHandle& pnh = *impl_->pnh;
  NodeParams& p = impl_->params;
  read_param(pnh, "config", p.config, "a string (file)");
  read_param(pnh, "calibration", p.calibration, "a string (file or folder)");
  read_param(pnh, "camera", p.camera, "an integer");
  read_param(pnh, "image_topic", p.image_topic, "a string");
  read_param(pnh, "imu_topic", p.imu_topic, "a string");
  read_param(pnh, "world_frame", p.world_frame, "a string");
  read_param(pnh, "robot_frame", p.robot_frame, "a string");
  read_param(pnh, "camera_frame", p.camera_frame, "a string");
  read_param(pnh, "queue_size", p.queue_size, "an integer");
  read_param(pnh, "imu_queue_size", p.imu_queue_size, "an integer");
  read_param(pnh, "map_every", p.map_every, "an integer");
  read_param(pnh, "trajectory", p.trajectory, "a string (file)");
  const std::string ns = pnh.getNamespace();
  // Unknown private parameters are errors (a misspelt name would otherwise leave a default in place silently).
  static const std::set<std::string> kKnown = {"config",     "calibration",    "camera",      "image_topic",
                                               "imu_topic",  "world_frame",    "robot_frame", "camera_frame",
                                               "queue_size", "imu_queue_size", "map_every",   "trajectory"};
  std::vector<std::string> names;
  if (impl_->nh->getParamNames(names)) {
    for (const std::string& name : names) {
      if (name.rfind(ns + "/", 0) != 0) continue;
      const std::string key = name.substr(ns.size() + 1);
      if (kKnown.count(key.substr(0, key.find('/'))) == 0) {
        throw ConfigError(
            fmt::format("unknown parameter {} (known: config, calibration, camera, image_topic, "
                        "imu_topic, world_frame, robot_frame, camera_frame, queue_size, imu_queue_size, "
                        "map_every, trajectory)",
                        name));
      }
    }
  }
  if (p.calibration.empty()) {
    throw ConfigError(
        fmt::format("parameter {}/calibration is required (a rig YAML, Kalibr camchain, EuRoC "
                    "sensor.yaml or EuRoC folder)",
                    ns));
  }
  if (p.camera < 0) throw ConfigError(fmt::format("parameter {}/camera = {} must be >= 0", ns, p.camera));
  if (p.queue_size < 1) throw ConfigError(fmt::format("parameter {}/queue_size = {} must be >= 1", ns, p.queue_size));
  if (p.imu_queue_size < 1) {
    throw ConfigError(fmt::format("parameter {}/imu_queue_size = {} must be >= 1", ns, p.imu_queue_size));
  }
  if (p.map_every < 0) throw ConfigError(fmt::format("parameter {}/map_every = {} must be >= 0", ns, p.map_every));
  if (p.image_topic.empty()) throw ConfigError(fmt::format("parameter {}/image_topic is empty", ns));
  if (p.world_frame.empty() || p.robot_frame.empty()) {
    throw ConfigError(fmt::format("parameters {0}/world_frame and {0}/robot_frame must not be empty", ns));
  }
}

RosBridge::~RosBridge() {
  impl_.reset();  // subscribers, publishers and node handles before the node shuts down
  ros::shutdown();
}

const NodeParams& RosBridge::params() const { return impl_->params; }

void RosBridge::start(std::function<void(io::ImageFrame)> on_image, std::function<void(const io::ImuSample&)> on_imu,
                      std::function<void(const std::string&)> on_bad_image, bool with_imu) {
  Impl& d = *impl_;
  d.odom_pub = d.pnh->advertise<nav_msgs::Odometry>("odom", 100);
  d.map_pub = d.pnh->advertise<sensor_msgs::PointCloud2>("map", 2);
  d.tf_pub = d.nh->advertise<tf2_msgs::TFMessage>("/tf", 100);
  const std::string image_topic = d.params.image_topic;
  const boost::function<void(const sensor_msgs::Image::ConstPtr&)> image_cb =
      [image_topic, on_image, on_bad_image](const sensor_msgs::Image::ConstPtr& msg) {
        const TimeNs t = to_ns(msg->header.stamp);
        std::string error;
        cv::Mat grey = io::grey_from_ros_image(msg->encoding, msg->width, msg->height, msg->step, msg->data.data(),
                                               msg->data.size(), &error);
        if (grey.empty()) {
          on_bad_image(fmt::format("{} message seq {} (t = {} s): {}", image_topic, msg->header.seq,
                                   io::format_seconds(t), error));
          return;
        }
        io::ImageFrame frame;
        frame.t = t;
        frame.camera = 0;
        frame.image = std::move(grey);
        frame.path = fmt::format("{}#{}", image_topic, msg->header.seq);
        on_image(std::move(frame));
      };
  d.image_sub =
      d.nh->subscribe<sensor_msgs::Image>(image_topic, static_cast<std::uint32_t>(d.params.queue_size), image_cb);
  if (with_imu) {
    const boost::function<void(const sensor_msgs::Imu::ConstPtr&)> imu_cb =
        [on_imu](const sensor_msgs::Imu::ConstPtr& msg) {
          io::ImuSample s;
          s.t = to_ns(msg->header.stamp);
          s.gyro = Eigen::Vector3d(msg->angular_velocity.x, msg->angular_velocity.y, msg->angular_velocity.z);
          s.accel = Eigen::Vector3d(msg->linear_acceleration.x, msg->linear_acceleration.y, msg->linear_acceleration.z);
          on_imu(s);
        };
    d.imu_sub =
        d.nh->subscribe<sensor_msgs::Imu>(d.params.imu_topic, static_cast<std::uint32_t>(d.params.imu_queue_size),
                                          imu_cb, ros::VoidConstPtr(), ros::TransportHints().tcpNoDelay());
  }
  logger("ros")->info("rtslam_ros: images from {}{}; publishing {}, {}, /tf ({} -> {})", image_topic,
                      with_imu ? ", IMU from " + d.params.imu_topic : std::string(" (IMU not used)"),
                      d.odom_pub.getTopic(), d.map_pub.getTopic(), d.params.world_frame, d.params.robot_frame);
}

void RosBridge::publish(const Estimate& e) {
  const Impl& d = *impl_;
  const ros::Time stamp = to_ros_time(e.t);
  nav_msgs::Odometry odom;
  odom.header.stamp = stamp;
  odom.header.frame_id = d.params.world_frame;
  odom.child_frame_id = d.params.robot_frame;
  odom.pose.pose.position.x = e.p_WR.x();
  odom.pose.pose.position.y = e.p_WR.y();
  odom.pose.pose.position.z = e.p_WR.z();
  odom.pose.pose.orientation.w = e.q_WR.w();
  odom.pose.pose.orientation.x = e.q_WR.x();
  odom.pose.pose.orientation.y = e.q_WR.y();
  odom.pose.pose.orientation.z = e.q_WR.z();
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) odom.pose.covariance[static_cast<std::size_t>(6 * i + j)] = e.cov_pose(i, j);
  }
  odom.twist.twist.linear.x = e.v_R.x();
  odom.twist.twist.linear.y = e.v_R.y();
  odom.twist.twist.linear.z = e.v_R.z();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) odom.twist.covariance[static_cast<std::size_t>(6 * i + j)] = e.cov_v_R(i, j);
  }
  if (e.w_R) {
    odom.twist.twist.angular.x = e.w_R->x();
    odom.twist.twist.angular.y = e.w_R->y();
    odom.twist.twist.angular.z = e.w_R->z();
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        odom.twist.covariance[static_cast<std::size_t>(6 * (3 + i) + 3 + j)] = e.cov_w_R ? (*e.cov_w_R)(i, j) : 0.0;
      }
    }
  } else {
    // No angular velocity in the state (inertial robot): marked unknown as sensor_msgs/Imu does, -1 on the diagonal.
    for (int i = 3; i < 6; ++i) odom.twist.covariance[static_cast<std::size_t>(6 * i + i)] = -1.0;
  }
  d.odom_pub.publish(odom);

  tf2_msgs::TFMessage tf;
  tf.transforms.push_back(transform(stamp, d.params.world_frame, d.params.robot_frame, e.p_WR, e.q_WR));
  if (!d.params.camera_frame.empty()) {
    tf.transforms.push_back(transform(stamp, d.params.robot_frame, d.params.camera_frame, e.T_RS.translation(),
                                      Eigen::Quaterniond(e.T_RS.rotation())));
  }
  d.tf_pub.publish(tf);

  if (e.with_map) {
    sensor_msgs::PointCloud2 cloud;
    cloud.header.stamp = stamp;
    cloud.header.frame_id = d.params.world_frame;
    cloud.height = 1;
    cloud.width = static_cast<std::uint32_t>(e.landmarks.size());
    const auto field = [](const char* name, std::uint32_t offset, std::uint8_t type) {
      sensor_msgs::PointField f;
      f.name = name;
      f.offset = offset;
      f.datatype = type;
      f.count = 1;
      return f;
    };
    cloud.fields = {field("x", 0, sensor_msgs::PointField::FLOAT32), field("y", 4, sensor_msgs::PointField::FLOAT32),
                    field("z", 8, sensor_msgs::PointField::FLOAT32), field("id", 12, sensor_msgs::PointField::UINT32)};
    cloud.is_bigendian = false;
    cloud.point_step = 16;
    cloud.row_step = cloud.point_step * cloud.width;
    cloud.is_dense = true;
    cloud.data.resize(cloud.row_step);
    for (std::size_t i = 0; i < e.landmarks.size(); ++i) {
      std::uint8_t* dst = cloud.data.data() + i * cloud.point_step;
      std::memcpy(dst, e.landmarks[i].data(), 3 * sizeof(float));
      const std::uint32_t id = i < e.landmark_ids.size() ? e.landmark_ids[i] : 0;
      std::memcpy(dst + 12, &id, sizeof id);
    }
    d.map_pub.publish(cloud);
  }
}

void RosBridge::spin() { ros::spin(); }

void RosBridge::request_shutdown() { ros::requestShutdown(); }

}  // namespace rtslam::ros_node
