#pragma once
// Options and start-up of the inertial robot of the image pipeline (issue "Inertial/visual SLAM"; MATH.md
// "Robots", inertial): the `imu:` section of a configuration, standstill detection, and the initial state
// [p q v a_b ω_b g] with its covariance from a window of IMU samples.
//
// Initialization uses the IMU samples of the `init_window` seconds before the first image they cover:
//  - standstill (gyro and accelerometer spreads below thresholds measured on the real EuRoC MAV, whose rotors make
//    it vibrate far above the datasheet densities — on V1_01, 1 s windows at rest: gyro std 0.02–0.085 rad/s,
//    accelerometer std 0.3–1.5 m/s²; in flight gyro std >= 0.12 rad/s): velocity ≈ 0, gyro bias = mean gyro,
//    gravity from the mean specific force;
//  - motion: velocity from the ground truth when there is one, else 0 with a large prior; gravity from the mean
//    specific force (samples rotated into W by the gyro over the window), less the window's mean acceleration when
//    the ground truth gives the velocity at both ends, else with a larger uncertainty.
// The gauge (p and q) has zero covariance, as for the constant-velocity robot; the attitude is the ground truth's
// when available (init_from_groundtruth) or identity, so gravity — a state, as the paper argues — carries the
// initial roll and pitch and their uncertainty.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <yaml-cpp/yaml.h>

#include "rtslam/core/time.hpp"
#include "rtslam/core/trajectory.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/calibration.hpp"
#include "rtslam/models/robots/inertial.hpp"

namespace rtslam::pipeline {

struct InertialOptions {
  std::string init = "auto";              // auto | standstill | motion
  double init_window_s = 0.5;             // IMU seconds used to initialize
  double standstill_max_gyro_std = 0.1;   // rad/s (norm of the per-axis std over the window)
  double standstill_max_accel_std = 1.6;  // m/s²
  double velocity_std_standstill = 0.05;  // m/s
  double velocity_std_motion = 1.0;       // m/s, without ground-truth velocity
  double velocity_std_groundtruth = 0.05; // m/s, with ground-truth velocity
  double accel_bias_std = 0.1;            // m/s² per axis (prior)
  double gyro_bias_std = 0.01;            // rad/s per axis (prior; standstill: the mean's spread, at least 1e-3)
  double gravity_std_standstill = 0.05;   // m/s² per axis, added to the accelerometer bias prior
  double gravity_std_motion = 1.0;        // m/s² per axis
  bool biases_from_groundtruth = false;   // start the biases at the ground truth's (EuRoC state CSV, simulator)
  double noise_scale = 1.0;               // multiplies the calibration's white-noise densities (vibration)
  double random_walk_scale = 1.0;         // multiplies the calibration's bias random walks
  std::optional<double> time_offset_s;    // t_imu = t_cam + t_d; default: the calibration's
  std::optional<double> gyro_saturation;  // rad/s per axis; default: the calibration's (none if unknown)
  std::optional<double> accel_saturation; // m/s² per axis; default: the calibration's
  bool estimate_extrinsics = false;       // camera–IMU T_RS as a map block, from the calibration with the prior:
  double extrinsics_std_m = 0.02;         //   position std (m, per axis) ...
  double extrinsics_std_deg = 1.0;        //   ... and rotation std (deg, per axis)
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
/// `gt` (may be null): the ground-truth pose at t (pose, and velocity/biases when it has them); `gt_start` (may be
/// null): the ground truth at t − window, whose velocity gives the window's mean acceleration in motion.
InertialStart initialize_inertial(const std::vector<ImuWindowSample>& window, TimeNs t, const InertialOptions& o,
                                  const StampedPose* gt, const StampedPose* gt_start = nullptr);

}  // namespace rtslam::pipeline
