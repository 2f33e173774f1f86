#pragma once
// The IMU noise a filter should assume, measured against a recording's ground-truth states (evaluation only: the
// estimator never reads ground truth). `rtslam imu-noise`; the procedure behind config/euroc_mono_imu.yaml.
//
// For a window length T and every ground-truth state k (time t_k, attitude q_WR, velocity v_WR in W, gyro bias b_w,
// accelerometer bias b_a) with a state j at t_k + T (within ±window_tolerance·T), the IMU samples of [t_k, t_j]
// (linearly interpolated at both ends) are integrated from state k with its biases, the midpoint rule of MATH.md:
//   ω̄ = ½(ω_i + ω_{i+1}) − b_w,  q_{i+1} = q_i ⊗ Exp(ω̄ Δt),
//   ā = ½(R_i (f_i − b_a) + R_{i+1} (f_{i+1} − b_a)) + g_W,  p += v Δt + ½ ā Δt²,  v += ā Δt,  g_W = (0, 0, −gravity),
// and compared with state j: the rotation residual δθ = Log(q̂_jᵀ ⊗ q_j) (rad, in R) and the velocity residual
// δv = v_j − v̂_j (m/s, in W). White noise of density σ_g (rad/s/√Hz) and σ_a (m/s²/√Hz) gives per-axis variances
// σ_g² T and σ_a² T, so the effective densities are
//   gyro  = sqrt(mean over windows and axes of δθ² / T),   accel = sqrt(mean over windows and axes of δv² / T).
// They include everything the filter's white noise must cover: vibration, the bias moving inside the window, and
// the ground truth's own error — hence larger than a datasheet's densities. Over short windows (50 ms) they are the
// white-noise densities to use; over long ones (1 s) the bias motion dominates (a walk of density σ_w adds
// σ_w² T³/3), and the effective density at 1 s, numerically the bias change per √s that would explain the whole
// residual, is the random walk to use.
// Windows are "at rest" when the ground-truth speed of every state inside them is below rest_speed, else "in
// flight". Windows over an IMU gap (a step longer than 2.5 times the median sample period) are skipped.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/io/calibration.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::eval {

struct ImuNoiseOptions {
  std::vector<double> windows_s = {0.05, 0.2, 1.0};  // window lengths T (s)
  double from_s = 0.0;              // windows starting this many seconds after the first state ...
  double to_s = 0.0;                // ... and ending before this many (0: the end)
  double rest_speed = 0.05;         // m/s: ground-truth speed below which a state is at rest
  double gravity = 9.81;            // m/s², along −z of W
  double window_tolerance = 0.1;    // the end state within ±this fraction of T from t_k + T
  void validate() const;            // ConfigError naming the option and its bound
};

/// Residual statistics of one set of windows.
struct ImuNoiseFigures {
  int windows = 0;
  double gyro_density = 0.0;   // rad/s/√Hz
  double accel_density = 0.0;  // m/s²/√Hz
  Eigen::Vector3d mean_rotation_residual = Eigen::Vector3d::Zero();  // rad, in R
  Eigen::Vector3d mean_velocity_residual = Eigen::Vector3d::Zero();  // m/s, in W
};

struct ImuNoiseWindow {
  double window_s = 0.0;
  ImuNoiseFigures all, rest, flight;
  int skipped_gaps = 0;  // windows over an IMU gap
};

/// Values for the `imu:` section of a configuration: white-noise densities from the shortest window, random walks
/// from the window closest to 1 s when one of 0.5 s or more was measured; in flight when the recording has both
/// rest and flight windows.
struct ImuNoiseSuggestion {
  double accelerometer_noise_density = 0.0;                // m/s²/√Hz
  double gyroscope_noise_density = 0.0;                    // rad/s/√Hz
  std::optional<double> accelerometer_random_walk;         // m/s³/√Hz
  std::optional<double> gyroscope_random_walk;             // rad/s²/√Hz
  std::string basis;                                       // which windows and subset they come from
};

struct ImuNoiseReport {
  std::vector<ImuNoiseWindow> windows;
  int states = 0;                 // ground-truth states in [from, to]
  int imu_samples = 0;
  double span_s = 0.0;            // seconds of ground truth used
  double imu_period_s = 0.0;      // median IMU sample period
  double rest_speed = 0.0;        // m/s, the option
  bool rest_and_flight = false;   // both kinds of windows found
  std::optional<ImuNoiseSuggestion> suggestion;  // absent when no window could be used
};

/// The figures above from time-ordered IMU samples (in the frame R of the states) and ground-truth states with
/// velocity and biases. Throws DataError when a state lacks velocity or biases, when the IMU does not overlap the
/// states, or when samples are not time-ordered.
ImuNoiseReport measure_imu_noise(const std::vector<io::ImuSample>& imu, const Trajectory& states,
                                 const ImuNoiseOptions& options = {});

/// The IMU samples, calibration and ground-truth states of an EuRoC folder ("euroc:DIR" or "DIR": imu0/data.csv,
/// imu0/sensor.yaml, state_groundtruth_estimate0/data.csv). Throws IoError naming the missing file.
struct ImuNoiseInput {
  std::vector<io::ImuSample> imu;
  std::optional<io::ImuCalibration> calibration;
  Trajectory states;
};
ImuNoiseInput read_imu_noise_input(const std::string& dataset_spec);

/// A printable report (per window: all / at rest / in flight), the datasheet's values when given, and the
/// suggested `imu:` lines.
std::string format_imu_noise(const ImuNoiseReport& report,
                             const std::optional<io::ImuCalibration>& calibration = std::nullopt);
nlohmann::json to_json(const ImuNoiseReport& report);

}  // namespace rtslam::eval
