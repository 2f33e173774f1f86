#pragma once
// Absolute sensors (paper: "any number of sensors", issue 15): a sensor on the robot that measures where it is in
// the world, not landmarks. Its world frame is the estimator's world frame W (see strategies/absolute.hpp for how
// the robot's start frame is brought into it).
//  - Position (GPS-like): the antenna A at T_RS = (I, p_RA) (the lever arm); datum PositionData, z = p_WA (m).
//  - Pose (motion capture): the marker body M at T_RS = T_RM (lever arm and rotation offset); datum PoseData,
//    z = T_WM.
// The measurement models and their Jacobians are models/sensors/absolute.hpp; the data manager that corrects the
// filter with them is strategies::AbsoluteDataManager. They observe no landmark (observes_landmarks() is false):
// the camera-only calls (project, back_project, in_field) answer false.
#include <string>

#include <Eigen/Core>

#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/sensor.hpp"

namespace rtslam::slam {

/// One position fix p_WA at t (antenna position in W, m). `cov` (m²): the fix's own covariance when the receiver
/// gives one (has_cov), else the sensor's configured noise applies.
struct PositionData final : RawData {
  Eigen::Vector3d p_WA = Eigen::Vector3d::Zero();
  bool has_cov = false;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Identity();
};

/// One pose T_WM of the marker body at t. `cov` over [δp (m²) δθ (rad², right perturbation)] when has_cov.
struct PoseData final : RawData {
  math::Pose T_WM;
  bool has_cov = false;
  Eigen::Matrix<double, 6, 6> cov = Eigen::Matrix<double, 6, 6>::Identity();
};

class AbsoluteSensor final : public Sensor {
 public:
  enum class Kind { Position, Pose };
  /// T_RS: (I, lever arm) for a position sensor, T_RM for a pose sensor.
  AbsoluteSensor(std::string name, Kind kind, math::Pose T_RS);
  Kind kind() const { return kind_; }
  int measurement_size() const override { return kind_ == Kind::Position ? 3 : 6; }
  bool observes_landmarks() const override { return false; }
  bool project(const Eigen::Vector3d&, Eigen::Vector2d&, Eigen::Matrix<double, 2, 3>*) const override { return false; }
  bool in_field(const Eigen::Vector2d&, double) const override { return false; }
  bool back_project(const Eigen::Vector2d&, Eigen::Vector3d&, Eigen::Matrix<double, 3, 2>*) const override {
    return false;
  }

 private:
  Kind kind_;
};

}  // namespace rtslam::slam
