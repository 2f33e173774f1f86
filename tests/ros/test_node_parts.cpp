// The ROS-free part of rtslam_ros (apps/rtslam_ros/): the pose covariance in ROS's convention. Built and run with or
// without ROS. (The live source between the ROS callbacks and the pipeline, io::LiveSource, is tested in
// tests/io/test_live_source.cpp.)
#include <gtest/gtest.h>

#include <cmath>

#include "estimate.hpp"

namespace rtslam::ros_node {
namespace {

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
