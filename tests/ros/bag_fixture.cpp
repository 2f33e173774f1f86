// Compiled as C++17 with the ROS headers (see bag_fixture.hpp).
#include "bag_fixture.hpp"

#include <rosbag/bag.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

namespace rtslam::ros_test {
namespace {

ros::Time to_ros_time(TimeNs t) {
  return ros::Time(static_cast<std::uint32_t>(t / kNsPerSecond), static_cast<std::uint32_t>(t % kNsPerSecond));
}

ros::Time receive_time(TimeNs receive, TimeNs stamp) { return to_ros_time(receive != 0 ? receive : stamp); }

}  // namespace

void write_bag(const std::string& path, const std::vector<RawMessage>& messages) {
  rosbag::Bag bag(path, rosbag::bagmode::Write);
  for (const RawMessage& m : messages) {
    if (const auto* image = std::get_if<RawImage>(&m)) {
      sensor_msgs::Image msg;
      msg.header.stamp = to_ros_time(image->stamp);
      msg.encoding = image->encoding;
      msg.width = image->width;
      msg.height = image->height;
      msg.step = image->step;
      msg.data = image->data;
      bag.write(image->topic, receive_time(image->receive, image->stamp), msg);
    } else if (const auto* compressed = std::get_if<RawCompressed>(&m)) {
      sensor_msgs::CompressedImage msg;
      msg.header.stamp = to_ros_time(compressed->stamp);
      msg.format = compressed->format;
      msg.data = compressed->data;
      bag.write(compressed->topic, receive_time(compressed->receive, compressed->stamp), msg);
    } else {
      const auto& imu = std::get<RawImu>(m);
      sensor_msgs::Imu msg;
      msg.header.stamp = to_ros_time(imu.stamp);
      msg.angular_velocity.x = imu.gyro.x();
      msg.angular_velocity.y = imu.gyro.y();
      msg.angular_velocity.z = imu.gyro.z();
      msg.linear_acceleration.x = imu.accel.x();
      msg.linear_acceleration.y = imu.accel.y();
      msg.linear_acceleration.z = imu.accel.z();
      bag.write(imu.topic, receive_time(imu.receive, imu.stamp), msg);
    }
  }
  bag.close();
}

}  // namespace rtslam::ros_test
