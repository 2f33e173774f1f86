#pragma once
// What rtslam_ros publishes after a processed image, taken from the pipeline's observer (ImageSlamFrame), in ROS's
// conventions. Kept free of ROS and of C++20-only headers: ros_bridge.cpp (C++17) includes it.
//
// Covariances: the filter's pose covariance is [δp δθ] with δp in W and δθ a right perturbation in R
// (q = q̂ ⊗ Exp(δθ), core/trajectory.hpp); nav_msgs/Odometry's pose covariance is (x, y, z, rotation about X, Y, Z)
// with the rotations about the fixed axes of the parent frame W, a left perturbation q = Exp(δφ) ⊗ q̂ with
// δφ = R_WR δθ. So cov_ros = J cov Jᵀ with J = diag(I, R_WR). The twist is in the child frame R: v_R = R_WRᵀ v_W,
// δv_R = R_WRᵀ δv_W + [v_R]× δθ.
#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "rtslam/core/time.hpp"

namespace rtslam::pipeline {
struct ImageSlamFrame;
}

namespace rtslam::ros_node {

struct Estimate {
  TimeNs t = 0;  // image time in the IMU clock
  Eigen::Vector3d p_WR = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_WR = Eigen::Quaterniond::Identity();
  Eigen::Matrix<double, 6, 6> cov_pose = Eigen::Matrix<double, 6, 6>::Zero();  // ROS order and convention
  Eigen::Vector3d v_R = Eigen::Vector3d::Zero();                               // linear velocity in R
  Eigen::Matrix3d cov_v_R = Eigen::Matrix3d::Zero();
  std::optional<Eigen::Vector3d> w_R;                      // angular velocity in R (constant-
  std::optional<Eigen::Matrix3d> cov_w_R;                  // velocity robot; none when inertial)
  Eigen::Isometry3d T_RS = Eigen::Isometry3d::Identity();  // the camera, for camera_frame
  bool with_map = false;                                   // publish the landmarks below
  std::vector<Eigen::Vector3f> landmarks;                  // positions in W
  std::vector<std::uint32_t> landmark_ids;
};

/// The filter's [δp δθ] pose covariance (δθ right, in R) as nav_msgs/Odometry's (rotations about W's axes).
Eigen::Matrix<double, 6, 6> pose_covariance_to_ros(const Eigen::Matrix<double, 6, 6>& cov,
                                                   const Eigen::Quaterniond& q_WR);

/// The estimate after `frame` (the robot of its map), with the camera extrinsics T_RS and, when `with_map`, every
/// landmark's position.
Estimate make_estimate(const pipeline::ImageSlamFrame& frame, const Eigen::Isometry3d& T_RS, bool with_map);

}  // namespace rtslam::ros_node
