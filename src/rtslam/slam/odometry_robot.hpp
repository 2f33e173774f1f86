#pragma once
// The odometry-driven robot [p q] (models/robots/odometry.hpp, RT-SLAM's RobotOdometry): odometry increments are
// its proprioceptive inputs (System::feed routes them by the robot's input id), as IMU samples are the inertial
// robot's. The robot can be predicted only up to its last increment; the System holds exteroceptive data until the
// increments cover them.
#include <optional>
#include <string>

#include "rtslam/core/ring_buffer.hpp"
#include "rtslam/models/robots/odometry.hpp"
#include "rtslam/slam/robot.hpp"

namespace rtslam::slam {

/// One odometry reading: the pose increment of the robot from the previous reading (t_from) to this one (t), in the
/// robot frame at t_from: dp the displacement (m), dtheta the rotation vector (rad) of R(t_from)ᵀ R(t).
struct OdometryData final : RawData {
  TimeNs t_from = 0;
  Eigen::Vector3d dp = Eigen::Vector3d::Zero();
  Eigen::Vector3d dtheta = Eigen::Vector3d::Zero();
};

/// predict_to(t) applies the buffered increments up to t in one covariance update (Φ = Π F_k, Q = Σ Φ_k G_k U_k
/// G_kᵀ Φ_kᵀ). An increment that straddles t is split in proportion of time (OdometryIncrement::scaled: its noise
/// splits in the same proportions); time between two increments that do not touch (a dropped reading) is taken as
/// no motion, with no noise.
class OdometryRobot final : public Robot {
 public:
  explicit OdometryRobot(models::OdometryParams params, std::string name = "robot");
  /// Applies the buffered increments up to t; DataError if they do not cover t. False if t is before the robot's time.
  bool predict_to(TimeNs t) override;
  bool needs_inputs() const override { return true; }
  /// An OdometryData; DataError if it is not one, is not finite, has t <= t_from or starts before the previous one
  /// ends.
  void add_input(const RawData& input) override;
  /// The end of the latest buffered increment; nullopt before the first.
  std::optional<TimeNs> coverage() const { return last_t_; }
  filter::BlockLayout layout() const override { return static_layout(); }
  /// [p q]: the pose moves with the world.
  void nullspace(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::MatrixXd> N) const override;
  static filter::BlockLayout static_layout();
  const models::OdometryParams& params() const { return params_; }
  long increments_applied() const { return steps_; }

 private:
  struct Increment {
    TimeNs t0 = 0, t1 = 0;
    models::OdometryIncrement u;
  };
  models::OdometryParams params_;
  RingBuffer<Increment> pending_{64};  // increments ending after time_ (reused: no allocation per reading)
  std::optional<TimeNs> last_t_;
  long steps_ = 0;
  models::Vector7d x_, fej_x_;
  models::Matrix6d F_, G_, U_, Phi_, Qacc_, tmp_;
  Eigen::Matrix<double, 6, 6> N_;
};

}  // namespace rtslam::slam
