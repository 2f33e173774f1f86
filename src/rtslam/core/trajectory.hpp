#pragma once
// A trajectory of timestamped poses T_WR (robot frame R in world W), optionally with velocity, IMU biases and the
// 6x6 pose covariance. The covariance convention is the filter's: rows/cols [δp(3) δθ(3)], position error in W
// (p = p̂ + δp) and orientation error as a right perturbation (q = q̂ ⊗ Exp(δθ), δθ in R).
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "rtslam/core/time.hpp"

namespace rtslam {

struct StampedPose {
  TimeNs t = 0;
  Eigen::Vector3d p_WR = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_WR = Eigen::Quaterniond::Identity();
  std::optional<Eigen::Vector3d> v_WR;              // velocity in W, when known
  std::optional<Eigen::Vector3d> gyro_bias;         // rad/s, when the robot has it
  std::optional<Eigen::Vector3d> accel_bias;        // m/s^2, when the robot has it
  std::optional<Eigen::Matrix<double, 6, 6>> cov;   // [δp δθ] covariance, filter convention (see above)
};

struct Trajectory {
  std::vector<StampedPose> poses;
  bool has_timestamps = true;  // false for KITTI pose files (associated by index)
  std::string source;          // file it came from, for messages
};

}  // namespace rtslam
