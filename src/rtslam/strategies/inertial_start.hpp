#pragma once
// The IMU-only start of the inertial robot (issue "Inertial/visual SLAM"; MATH.md "Robots", inertial): standstill
// detection and the initial state [p q v a_b ω_b g] with its covariance from a window of IMU samples — from the
// sensors alone (the visual-inertial start, vi_init.hpp, builds on it; the options are read in pipeline/inertial_init).
//
// The world frame is gravity-aligned with the origin and yaw of the first pose (as OpenVINS and ROVIO do): p = 0,
// q rotates the window's mean specific force (each sample rotated by the gyro to the attitude at t) onto +z, with
// the yaw that makes W's x axis the horizontal projection of the most horizontal body axis; g starts as the
// opposite of that force, (0, 0, −|f|), and stays a state (the paper: better for linearity than constraining q).
// The gauge (p and q) has zero covariance. Velocity, biases and gravity get priors:
//  - standstill (`init: standstill`, or `auto` when the gyro and accelerometer spreads are below thresholds measured
//    on the real EuRoC MAV, whose rotors make it vibrate far above the datasheet densities — on V1_01, 1 s windows
//    at rest: gyro std 0.02–0.085 rad/s, accelerometer std 0.3–1.5 m/s²): v ≈ 0 (velocity_std_standstill),
//    gyro bias = the mean gyro, |g| from the mean specific force;
//  - otherwise v = 0 with the broad velocity_std_motion and gravity with gravity_std_motion (the window's unknown
//    mean acceleration). The IMU alone cannot tell a constant-velocity motion from rest, nor vibration from slow
//    motion: the in-motion priors also hold at rest (the filter then finds v = 0 from the images), so a preset can
//    choose conservative thresholds.
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "rtslam/core/time.hpp"
#include "rtslam/models/robots/inertial.hpp"

namespace rtslam::strategies {

/// The start's keys of the `imu:` section.
struct InertialStartOptions {
  std::string init = "auto";              // auto | standstill | motion
  double init_window_s = 0.5;             // IMU seconds used to initialize
  double standstill_max_gyro_std = 0.1;   // rad/s (norm of the per-axis std over the window)
  double standstill_max_accel_std = 1.6;  // m/s²
  double velocity_std_standstill = 0.05;  // m/s
  double velocity_std_motion = 1.0;       // m/s, in motion (unknown velocity)
  double accel_bias_std = 0.1;            // m/s² per axis (prior)
  double gyro_bias_std = 0.01;            // rad/s per axis (prior; standstill: the mean's spread, at least 1e-3)
  double gravity_std_standstill = 0.05;   // m/s² per axis, added to the accelerometer bias prior
  double gravity_std_motion = 1.0;        // m/s² per axis
  double gravity_magnitude = 9.81;        // m/s², |g| where the robot runs (9.78 at the equator, 9.83 at the poles)
  double gravity_magnitude_std = 0.03;    // m/s²: |g| is known; without it an accelerometer bias along the
                                          // vertical trades against |g| and the filter scales its motion wrongly
  /// ConfigError naming imu/<key> and its bounds.
  void validate() const;
};

struct ImuWindowSample {
  TimeNs t = 0;
  models::ImuMeasurement m;
};

struct InertialStart {
  models::Vector19d x = models::Vector19d::Zero();
  Eigen::Matrix<double, 18, 18> P = Eigen::Matrix<double, 18, 18>::Zero();
  bool standstill = false;
  double gyro_std = 0.0, accel_std = 0.0;  // spreads measured over the window
  int samples = 0;
  std::string describe() const;            // one line for the log and the summary
};

/// The initial state at time t from the samples of [t − window, t] (at least 10 of them; DataError otherwise).
InertialStart initialize_inertial(const std::vector<ImuWindowSample>& window, TimeNs t, const InertialStartOptions& o);

/// The prior of [v a_b ω_b g] (tangent 18 × 18, zero on the pose rows) with these standard deviations; g = −R f̄
/// absorbs the accelerometer bias error rotated into W, so g's block gets ab_std² + g_std² and its correlation with
/// a_b is ab_std² R_WR.
Eigen::Matrix<double, 18, 18> prior_covariance(double v_std, double ab_std, double wb_std, double g_std,
                                               const Eigen::Matrix3d& R_WR);

/// The in-motion prior of [v a_b ω_b g] (tangent 18 × 18, zero on the pose rows): velocity_std_motion,
/// accel_bias_std, gyro_bias_std, gravity_std_motion with g's correlation to a_b through R_WR. For starts in motion
/// and the health monitor's re-initializations.
/// The start's prior (s.x, s.P) fused with the pseudo-measurement |g| = o.gravity_magnitude (std
/// o.gravity_magnitude_std): one scalar Kalman update over the velocity, biases and gravity.
void constrain_gravity_magnitude(InertialStart& s, const InertialStartOptions& o);
Eigen::Matrix<double, 18, 18> motion_prior_covariance(const InertialStartOptions& o, const Eigen::Matrix3d& R_WR);

/// The gravity-aligned attitude q_WR of a body whose mean specific force (in R) is f_R: R_WR f_R ∝ +z, W's x axis
/// along the horizontal projection of the body axis most orthogonal to f_R.
Eigen::Quaterniond gravity_aligned_attitude(const Eigen::Vector3d& f_R);

}  // namespace rtslam::strategies
