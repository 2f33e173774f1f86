// The ROS-free parts of rtslam_ros (apps/rtslam_ros/): the live source between the ROS callbacks and the pipeline,
// and the pose covariance in ROS's convention. Built and run with or without ROS.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

#include "estimate.hpp"
#include "live_source.hpp"
#include "rtslam/core/error.hpp"

namespace rtslam::ros_node {
namespace {

io::ImageFrame image_at(TimeNs t) {
  io::ImageFrame f;
  f.t = t;
  f.image = cv::Mat(2, 2, CV_8UC1, cv::Scalar(static_cast<double>(t % 200)));
  f.path = "test#" + std::to_string(t);
  return f;
}

io::ImuSample imu_at(TimeNs t) {
  io::ImuSample s;
  s.t = t;
  s.accel = Eigen::Vector3d(0.0, 0.0, 9.81);
  return s;
}

/// (t, is image) of a measurement.
std::pair<TimeNs, bool> tag(const std::optional<io::Measurement>& m) {
  EXPECT_TRUE(m.has_value());
  if (!m) return {-1, false};
  return {io::time_of(*m), std::holds_alternative<io::ImageFrame>(*m)};
}

TEST(LiveSource, AnImageWaitsForTheImuSampleThatCoversIt) {
  LiveSource::Options o;
  o.with_imu = true;
  o.max_image_wait_s = 30.0;
  LiveSource src(o);
  src.push_image(image_at(10));
  src.push_imu(imu_at(5));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{5}, false));
  std::thread late_imu([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    src.push_imu(imu_at(10));
    src.push_imu(imu_at(15));
  });
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{10}, false));  // IMU first at equal times
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{10}, true));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{15}, false));
  late_imu.join();
  src.close();
  EXPECT_FALSE(src.next().has_value());
  EXPECT_EQ(src.stats().images, 1u);
  EXPECT_EQ(src.stats().imu_samples, 3u);
}

TEST(LiveSource, WithoutImuImagesGoThroughAtOnce) {
  LiveSource src(LiveSource::Options{});
  src.push_image(image_at(10));
  src.push_image(image_at(20));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{10}, true));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{20}, true));
}

TEST(LiveSource, AnImageWaitsForTheImuAtMostTheMaximumWait) {
  LiveSource::Options o;
  o.with_imu = true;
  o.max_image_wait_s = 0.05;
  LiveSource src(o);
  const auto start = std::chrono::steady_clock::now();
  src.push_image(image_at(10));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{10}, true));
  EXPECT_GE(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(45));
}

TEST(LiveSource, BadStampsAndValuesAreSkippedAndCounted) {
  LiveSource::Options o;
  o.with_imu = true;
  LiveSource src(o);
  src.push_imu(imu_at(5));
  src.push_imu(imu_at(5));  // duplicate
  src.push_imu(imu_at(3));  // backwards
  io::ImuSample nan = imu_at(7);
  nan.gyro.x() = std::numeric_limits<double>::quiet_NaN();
  src.push_imu(nan);
  src.push_imu(imu_at(20));
  src.push_image(image_at(10));
  src.push_image(image_at(10));  // duplicate
  src.push_image(image_at(8));   // backwards
  src.report_bad_image("/cam0/image_raw message seq 3: encoding 'mono16' is not supported");
  src.close();
  std::vector<std::pair<TimeNs, bool>> got;
  while (auto m = src.next()) got.emplace_back(io::time_of(*m), std::holds_alternative<io::ImageFrame>(*m));
  EXPECT_EQ(got, (std::vector<std::pair<TimeNs, bool>>{{5, false}, {10, true}, {20, false}}));
  const io::SourceStats& s = src.stats();
  EXPECT_EQ(s.duplicate_timestamps, 2u);
  EXPECT_EQ(s.backwards_timestamps, 2u);
  EXPECT_EQ(s.non_finite, 1u);
  EXPECT_EQ(s.undecodable_images, 1u);
  EXPECT_EQ(s.messages.size(), 6u);
}

TEST(LiveSource, AFullQueueDropsItsOldestElement) {
  LiveSource::Options o;
  o.image_capacity = 2;
  o.imu_capacity = 1;
  LiveSource src(o);
  for (TimeNs t : {10, 20, 30}) src.push_image(image_at(t));
  src.push_imu(imu_at(1));
  src.push_imu(imu_at(2));
  EXPECT_EQ(src.dropped_images(), 1u);
  EXPECT_EQ(src.dropped_imu_samples(), 1u);
  src.close();
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{2}, false));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{20}, true));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{30}, true));
  EXPECT_FALSE(src.next().has_value());
  src.push_image(image_at(40));  // after close: ignored
  EXPECT_FALSE(src.next().has_value());
}

TEST(LiveSource, ProducerThreadsAndTheConsumerSeeOneTimeOrderedStream) {
  LiveSource::Options o;
  o.with_imu = true;
  o.image_capacity = 1000;
  o.imu_capacity = 10000;
  o.max_image_wait_s = 30.0;
  LiveSource src(o);
  constexpr int kImages = 50;
  constexpr int kImuPerImage = 10;
  // The camera's messages arrive before the IMU samples that cover them (as when the IMU driver lags): the source
  // holds each image until its IMU has come, so the consumer sees one time-ordered stream.
  std::thread producers([&] {
    std::thread image_thread([&] {
      for (int k = 0; k < kImages; ++k) src.push_image(image_at(100 + 100 * k + 5));
    });
    image_thread.join();
    std::thread imu_thread([&] {
      for (int k = 0; k <= kImages * kImuPerImage; ++k) src.push_imu(imu_at(100 + 10 * k));
    });
    imu_thread.join();
    src.close();
  });
  std::size_t images = 0, imu = 0;
  TimeNs last = std::numeric_limits<TimeNs>::min();
  bool ordered = true;
  while (auto m = src.next()) {
    ordered = ordered && io::time_of(*m) >= last;
    last = io::time_of(*m);
    (std::holds_alternative<io::ImageFrame>(*m) ? images : imu) += 1;
  }
  producers.join();
  EXPECT_TRUE(ordered);
  EXPECT_EQ(images, static_cast<std::size_t>(kImages));
  EXPECT_EQ(imu, static_cast<std::size_t>(kImages * kImuPerImage + 1));
}

TEST(LiveSource, RefusesEmptyQueues) {
  LiveSource::Options o;
  o.image_capacity = 0;
  EXPECT_THROW(LiveSource{o}, ConfigError);
}

TEST(PoseCovarianceToRos, IdentityOrientationKeepsTheCovariance) {
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Random();
  const Eigen::Matrix<double, 6, 6> cov = A * A.transpose();
  EXPECT_TRUE(pose_covariance_to_ros(cov, Eigen::Quaterniond::Identity()).isApprox(cov, 1e-15));
}

TEST(PoseCovarianceToRos, RotationUncertaintyMovesToTheWorldAxes) {
  // R is W turned 90 deg about z: R's x axis is W's y axis. An uncertain rotation about R's x (the filter's right
  // perturbation) is an uncertain rotation about W's y (ROS's fixed axes); positions are in W already.
  const Eigen::Quaterniond q_WR(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  Eigen::Matrix<double, 6, 6> cov = Eigen::Matrix<double, 6, 6>::Zero();
  cov(0, 0) = 1.0;  // x
  cov(3, 3) = 4.0;  // δθ about R's x
  cov(0, 3) = cov(3, 0) = 0.5;
  const Eigen::Matrix<double, 6, 6> ros = pose_covariance_to_ros(cov, q_WR);
  EXPECT_NEAR(ros(0, 0), 1.0, 1e-12);
  EXPECT_NEAR(ros(3, 3), 0.0, 1e-12);
  EXPECT_NEAR(ros(4, 4), 4.0, 1e-12);  // about W's y
  EXPECT_NEAR(ros(0, 4), 0.5, 1e-12);
  EXPECT_NEAR(ros(4, 0), 0.5, 1e-12);
  EXPECT_TRUE(ros.isApprox(ros.transpose(), 0.0));
}

}  // namespace
}  // namespace rtslam::ros_node
