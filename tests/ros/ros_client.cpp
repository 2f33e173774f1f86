// Compiled as C++17 with the ROS headers (see ros_client.hpp).
#include "ros_client.hpp"

#include <mutex>

#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

namespace rtslam::ros_test {
namespace {

TimeNs to_ns(const ros::Time& t) { return static_cast<TimeNs>(t.sec) * kNsPerSecond + static_cast<TimeNs>(t.nsec); }

ros::Time to_ros_time(TimeNs t) {
  return ros::Time(static_cast<std::uint32_t>(t / kNsPerSecond), static_cast<std::uint32_t>(t % kNsPerSecond));
}

template <class Pred>
bool poll(double timeout_s, Pred pred) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (!pred()) {
    if (ros::WallTime::now() > end) return false;
    ros::WallDuration(0.02).sleep();
  }
  return true;
}

}  // namespace

struct RosTestClient::Impl {
  std::unique_ptr<ros::NodeHandle> nh;
  std::unique_ptr<ros::AsyncSpinner> spinner;
  ros::Publisher image_pub;
  ros::Publisher imu_pub;
  ros::Subscriber odom_sub;
  ros::Subscriber tf_sub;
  ros::Subscriber map_sub;
  mutable std::mutex mutex;
  std::vector<ReceivedOdometry> odometry;
  std::vector<ReceivedTransform> transforms;
  std::size_t map_messages = 0;
  std::size_t last_map_points = 0;
  std::vector<std::string> last_map_fields;
  std::uint32_t seq = 0;
};

RosTestClient::RosTestClient(const std::string& name, const std::string& image_topic, const std::string& imu_topic,
                             const std::string& odom_topic, const std::string& map_topic)
    : impl_(std::make_unique<Impl>()) {
  if (!ros::isInitialized()) ros::init(ros::M_string(), name, ros::init_options::NoSigintHandler);
  Impl& d = *impl_;
  d.nh = std::make_unique<ros::NodeHandle>();
  d.image_pub = d.nh->advertise<sensor_msgs::Image>(image_topic, 1000);
  d.imu_pub = d.nh->advertise<sensor_msgs::Imu>(imu_topic, 10000);
  Impl* p = impl_.get();
  d.odom_sub = d.nh->subscribe<nav_msgs::Odometry>(
      odom_topic, 10000,
      boost::function<void(const nav_msgs::Odometry::ConstPtr&)>([p](const nav_msgs::Odometry::ConstPtr& m) {
        ReceivedOdometry o;
        o.t = to_ns(m->header.stamp);
        o.frame_id = m->header.frame_id;
        o.child_frame_id = m->child_frame_id;
        o.p = Eigen::Vector3d(m->pose.pose.position.x, m->pose.pose.position.y, m->pose.pose.position.z);
        o.q = Eigen::Quaterniond(m->pose.pose.orientation.w, m->pose.pose.orientation.x, m->pose.pose.orientation.y,
                                 m->pose.pose.orientation.z);
        for (std::size_t i = 0; i < 36; ++i) o.pose_covariance[i] = m->pose.covariance[i];
        std::lock_guard lock(p->mutex);
        p->odometry.push_back(o);
      }));
  d.tf_sub = d.nh->subscribe<tf2_msgs::TFMessage>(
      "/tf", 10000,
      boost::function<void(const tf2_msgs::TFMessage::ConstPtr&)>([p](const tf2_msgs::TFMessage::ConstPtr& m) {
        std::lock_guard lock(p->mutex);
        for (const auto& T : m->transforms) {
          p->transforms.push_back({to_ns(T.header.stamp), T.header.frame_id, T.child_frame_id});
        }
      }));
  d.map_sub = d.nh->subscribe<sensor_msgs::PointCloud2>(
      map_topic, 100,
      boost::function<void(const sensor_msgs::PointCloud2::ConstPtr&)>(
          [p](const sensor_msgs::PointCloud2::ConstPtr& m) {
            std::lock_guard lock(p->mutex);
            ++p->map_messages;
            p->last_map_points = static_cast<std::size_t>(m->width) * m->height;
            p->last_map_fields.clear();
            for (const auto& f : m->fields) p->last_map_fields.push_back(f.name);
          }));
  d.spinner = std::make_unique<ros::AsyncSpinner>(1);
  d.spinner->start();
}

RosTestClient::~RosTestClient() {
  impl_->spinner->stop();
  impl_.reset();
  ros::shutdown();
}

bool RosTestClient::wait_for_subscribers(std::size_t n, bool imu, double timeout_s) {
  return poll(timeout_s, [&] {
    return impl_->image_pub.getNumSubscribers() >= n && (!imu || impl_->imu_pub.getNumSubscribers() >= n);
  });
}

bool RosTestClient::wait_for_publishers(std::size_t n, double timeout_s) {
  return poll(timeout_s, [&] {
    return impl_->odom_sub.getNumPublishers() >= n && impl_->map_sub.getNumPublishers() >= n &&
           impl_->tf_sub.getNumPublishers() >= n;
  });
}

void RosTestClient::clear() {
  std::lock_guard lock(impl_->mutex);
  impl_->odometry.clear();
  impl_->transforms.clear();
  impl_->map_messages = 0;
  impl_->last_map_points = 0;
  impl_->last_map_fields.clear();
}

void RosTestClient::publish(const io::Measurement& m) {
  if (const auto* s = std::get_if<io::ImuSample>(&m)) {
    sensor_msgs::Imu msg;
    msg.header.stamp = to_ros_time(s->t);
    msg.header.frame_id = "imu0";
    msg.angular_velocity.x = s->gyro.x();
    msg.angular_velocity.y = s->gyro.y();
    msg.angular_velocity.z = s->gyro.z();
    msg.linear_acceleration.x = s->accel.x();
    msg.linear_acceleration.y = s->accel.y();
    msg.linear_acceleration.z = s->accel.z();
    impl_->imu_pub.publish(msg);
    return;
  }
  const auto& f = std::get<io::ImageFrame>(m);
  sensor_msgs::Image msg;
  msg.header.seq = impl_->seq++;
  msg.header.stamp = to_ros_time(f.t);
  msg.header.frame_id = "cam0";
  msg.width = static_cast<std::uint32_t>(f.image.cols);
  msg.height = static_cast<std::uint32_t>(f.image.rows);
  msg.encoding = "mono8";
  msg.step = msg.width;
  msg.data.resize(static_cast<std::size_t>(msg.step) * msg.height);
  for (int r = 0; r < f.image.rows; ++r) {
    std::copy_n(f.image.ptr<std::uint8_t>(r), msg.width, msg.data.data() + static_cast<std::size_t>(r) * msg.step);
  }
  impl_->image_pub.publish(msg);
}

bool RosTestClient::wait_for_odometry(std::size_t n, double timeout_s) {
  return poll(timeout_s, [&] {
    std::lock_guard lock(impl_->mutex);
    return impl_->odometry.size() >= n;
  });
}

std::vector<ReceivedOdometry> RosTestClient::odometry() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->odometry;
}

std::vector<ReceivedTransform> RosTestClient::transforms() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->transforms;
}

std::size_t RosTestClient::map_messages() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->map_messages;
}

std::size_t RosTestClient::last_map_points() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->last_map_points;
}

std::vector<std::string> RosTestClient::last_map_fields() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->last_map_fields;
}

}  // namespace rtslam::ros_test
