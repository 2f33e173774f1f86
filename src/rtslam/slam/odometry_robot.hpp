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

/// The map's scale kept at the odometry's (OdometryRobot, `odometry/rescale`). With one camera the EKF makes the
/// map's scale from the odometry badly: each update linearizes the inverse distances at a baseline that carries
/// that frame's odometry error, and the map ends up deeper (and the path longer) by up to 10-20 % while its shape
/// stays right (docs/odometry-scale.md). The robot therefore compares, over windows of `window_m` metres of odometry,
/// its estimated displacement (posterior to posterior) with the odometry's own (composed increments, turned into
/// the world by the estimated attitude at the window's start), and takes the scale factor s that maps the first onto
/// the second by weighted least squares over every window so far (weights: the inverse of each window's odometry
/// variance, σ_p² T + k_p² L per axis). Once the standard error of s is below `max_se` and s differs from 1 by more
/// than `min_z` standard errors (the map's scale is not the odometry's), the whole map's unit of length is changed by
/// s (Map::scale_lengths) and the windows so far are re-expressed in the new unit, so that later windows only correct
/// what the filter drifts by afterwards. The map is rescaled about the robot's start (its world frame's gauge point,
/// or the pose it was given), and only while the robot is alone in its map (several robots' known start poses are
/// metric: their map's scale is not the odometry's alone).
struct OdometryScaleOptions {
  bool enabled = false;   // the builder turns it on for one camera without an absolute sensor (odometry/rescale)
  double window_m = 0.5;  // odometry distance per window, m
  double max_se = 0.05;   // standard error of the scale factor below which the map is rescaled
  double min_z = 0.0;     // ... when the factor differs from 1 by more than min_z standard errors
  /// ConfigError naming the key (odometry/rescale_window, rescale_max_se, rescale_min_z) out of range.
  void validate() const;
};

/// predict_to(t) applies the buffered increments up to t in one covariance update (Φ = Π F_k, Q = Σ Φ_k G_k U_k
/// G_kᵀ Φ_kᵀ). An increment that straddles t is split in proportion of time (OdometryIncrement::scaled: its noise
/// splits in the same proportions); time between two increments that do not touch (a dropped reading) is taken as
/// no motion, with no noise.
class OdometryRobot final : public Robot {
 public:
  explicit OdometryRobot(models::OdometryParams params, std::string name = "robot", OdometryScaleOptions scale = {});
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
  /// Whether it keeps its map's scale at the odometry's (OdometryScaleOptions::enabled, and not given up), the map
  /// rescales made so far and the product of their factors.
  bool keeps_scale() const;
  int rescales() const { return rescales_; }
  double rescale_product() const { return rescale_product_; }
  bool can_scale_lengths() const override { return true; }
  /// p about the centre (the first estimate too).
  void scale_lengths(double c, const Eigen::Vector3d& centre, Eigen::Ref<Eigen::VectorXd> mean,
                     Eigen::Ref<Eigen::VectorXd> d) override;

 protected:
  void restarted() override;

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

  // Scale keeping (OdometryScaleOptions): the current window's start (posterior position and attitude) and the
  // odometry composed since then, in the robot frame at the start; the least-squares sums of the windows so far.
  void keep_scale();
  OdometryScaleOptions scale_;
  bool window_open_ = false;
  std::optional<Eigen::Vector3d> start_p_;  // where the map began: the centre of its rescales
  Eigen::Vector3d window_p_ = Eigen::Vector3d::Zero(), odo_p_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d window_R_ = Eigen::Matrix3d::Identity(), odo_R_ = Eigen::Matrix3d::Identity();
  double odo_length_ = 0.0, odo_time_ = 0.0;
  double sum_os_ = 0.0, sum_ss_ = 0.0;  // Σ w Δoᵀ Δs, Σ w |Δs|²
  int rescales_ = 0;
  double rescale_product_ = 1.0;
};

}  // namespace rtslam::slam
