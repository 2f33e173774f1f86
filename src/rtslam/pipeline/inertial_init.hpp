#pragma once
// Options and start-up of the inertial robot of the image pipeline (issue "Inertial/visual SLAM"; MATH.md
// "Robots", inertial): the `imu:` section of a configuration, standstill detection, and the initial state
// [p q v a_b ω_b g] with its covariance from a window of IMU samples — from the sensors alone.
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
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <yaml-cpp/yaml.h>

#include "rtslam/calib/check.hpp"
#include "rtslam/core/time.hpp"
#include "rtslam/core/trajectory.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/calibration.hpp"
#include "rtslam/models/robots/inertial.hpp"

namespace rtslam::pipeline {

struct ViInitOptions {
  bool enabled = true;
  double window_s = 0.4;                      // images used: the first window_s seconds ...
  double max_window_s = 2.0;                  // ... growing up to this while parallax or excitation lack
  double min_excitation_m = 0.1;              // m: displacement the accelerations must cause over the window
  double max_wait_s = 1.0;                    // s of failed windows before the IMU-only start takes over
  int min_frames = 5;
  int min_track_frames = 5;                   // images a feature must be tracked over (not the whole window)
  int cells_x = 8, cells_y = 5;               // feature grid (one Harris corner per cell)
  int patch_size = 15;                        // ZNCC template (odd)
  double min_score = 0.8;                     // ZNCC acceptance
  double search_px = 40.0;                    // half-size of the search box around the rotation-predicted position
  int min_features = 12;                      // tracked over min_track_frames images or more
  double standstill_max_disparity_px = 1.0;   // median feature displacement over the window: at rest below this
  double min_parallax_px = 8.0;               // median displacement after derotation needed for the dynamic solution
  double max_reprojection_px = 2.0;           // RMS of the solution's reprojection errors
  double gravity = 9.81;                      // m/s², the magnitude |g| imposed
  double max_speed = 20.0;                    // m/s: a larger v₀ is rejected
  double max_split_gravity_deg = 1.5;         // the window's first and last two thirds solved apart: gravity and
  double max_split_velocity_ratio = 0.1;      // velocity must agree within these (velocity: 0.05 m/s + ratio·|v₀|)
  // m/s², the refinement's prior on the accelerometer bias. Tighter than the filter's (imu/accel_bias_std): over a
  // window of under a second the bias is barely separable from gravity's direction and the velocity, and a free bias
  // fits the tracking noise with a wrong sign (0.3 m/s² off on recorded EuRoC windows, a 10 % error of |v0|, a scale
  // error the filter keeps). The filter starts from the window's estimate with its own, broader prior.
  double accel_bias_std = 0.02;
  bool refine_gyro_bias = true;               // the maximum-likelihood refinement also estimates the gyro bias
  void validate() const;
};
/// imu/vi_init: {enabled, window, min_frames, cells_x, cells_y, patch_size, min_score, search_px, min_features,
/// standstill_max_disparity_px, min_parallax_px, max_reprojection_px, gravity, max_speed}.
void read_vi_init(YamlMap section, ViInitOptions& o);
YAML::Node vi_init_to_yaml(const ViInitOptions& o);

struct InertialOptions {
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
  // The noise model: the calibration's densities (sensor.yaml / imu.yaml), each replaced by its key when given,
  // then multiplied by the scales.
  std::optional<double> accelerometer_noise_density;  // m/s²/√Hz
  std::optional<double> gyroscope_noise_density;      // rad/s/√Hz
  std::optional<double> accelerometer_random_walk;    // m/s³/√Hz
  std::optional<double> gyroscope_random_walk;        // rad/s²/√Hz
  double noise_scale = 1.0;               // multiplies the calibration's white-noise densities (vibration)
  double random_walk_scale = 1.0;         // multiplies the calibration's bias random walks
  std::optional<double> time_offset_s;    // t_imu = t_cam + t_d; default: the calibration's
  std::optional<double> gyro_saturation;  // rad/s per axis; default: the calibration's (none if unknown)
  std::optional<double> accel_saturation; // m/s² per axis; default: the calibration's
  bool estimate_extrinsics = false;       // camera–IMU T_RS as a map block, from the calibration with the prior:
  double extrinsics_std_m = 0.02;         //   position std (m, per axis) ...
  double extrinsics_std_deg = 1.0;        //   ... and rotation std (deg, per axis)
  ViInitOptions vi_init;                  // the visual-inertial start (vi_init.hpp); disabled: IMU-only start
  calib::CheckOptions calibration_check;  // `rtslam run`'s check of T_RS and t_d against the data (calib/check.hpp)
  void validate() const;
};

/// imu: {init, init_window, standstill_max_gyro_std, ...} (keys as the fields, init_window in s).
void read_inertial(YamlMap section, InertialOptions& o);
YAML::Node inertial_to_yaml(const InertialOptions& o);

/// The model's noise densities from a calibration and the option scales (ConfigError if the calibration is absent).
models::InertialParams inertial_params(const std::optional<io::ImuCalibration>& imu, const InertialOptions& o,
                                       const std::string& dataset);

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
InertialStart initialize_inertial(const std::vector<ImuWindowSample>& window, TimeNs t, const InertialOptions& o);

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
void constrain_gravity_magnitude(InertialStart& s, const InertialOptions& o);
Eigen::Matrix<double, 18, 18> motion_prior_covariance(const InertialOptions& o, const Eigen::Matrix3d& R_WR);

/// The gravity-aligned attitude q_WR of a body whose mean specific force (in R) is f_R: R_WR f_R ∝ +z, W's x axis
/// along the horizontal projection of the body axis most orthogonal to f_R.
Eigen::Quaterniond gravity_aligned_attitude(const Eigen::Vector3d& f_R);

}  // namespace rtslam::pipeline
