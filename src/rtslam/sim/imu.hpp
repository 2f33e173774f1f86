#pragma once
// IMU synthesis from a continuous trajectory (../shared/MATH.md, "Robots"):
//   gyro  = w_R + b_g + n_g,                 b_g' = n_bg
//   accel = R_WRᵀ (a_W − g_W) + b_a + n_a,   b_a' = n_ba
// with continuous-time densities: white noise of density σ (rad/s/√Hz, m/s²/√Hz) sampled at rate f has discrete
// standard deviation σ·√f; a bias random walk of density σ_b (rad/s²/√Hz, m/s³/√Hz) gains variance σ_b²·dt per
// step. Defaults are EuRoC's ADIS16448 values (mav0/imu0/sensor.yaml). Optional saturation clamps each axis (the
// RT-SLAM paper's IMU saturated at 300 deg/s). Every random draw comes from the generator given at construction.
#include <optional>

#include <Eigen/Core>

#include "rtslam/core/random.hpp"
#include "rtslam/core/time.hpp"
#include "rtslam/sim/trajectory.hpp"

namespace rtslam {
class YamlMap;
}

namespace rtslam::sim {

struct ImuNoiseOptions {
  double gyro_noise_density = 1.6968e-04;   // rad/s/√Hz
  double gyro_random_walk = 1.9393e-05;     // rad/s²/√Hz
  double accel_noise_density = 2.0e-3;      // m/s²/√Hz
  double accel_random_walk = 3.0e-3;        // m/s³/√Hz
};

struct ImuSynthOptions {
  double rate_hz = 200.0;
  ImuNoiseOptions noise;
  bool noise_enabled = true;                // false: exact samples (biases still applied)
  double gravity = 9.81;                    // m/s², g_W = (0, 0, −gravity)
  double initial_gyro_bias_std = 0.005;     // rad/s per axis, drawn once per run
  double initial_accel_bias_std = 0.05;     // m/s² per axis, drawn once per run
  double gyro_saturation_deg_s = 0.0;       // per-axis clamp; 0 = none
  double accel_saturation = 0.0;            // m/s² per-axis clamp; 0 = none

  /// Reads the keys above (rate_hz, gyroscope_noise_density, gyroscope_random_walk, accelerometer_noise_density,
  /// accelerometer_random_walk, noise, gravity, initial_gyro_bias_std, initial_accel_bias_std,
  /// gyro_saturation_deg_s, accel_saturation) from a mapping; unknown keys are left for the caller's finish().
  void read(YamlMap& map);
  /// Throws ConfigError naming `where` and the key if a value is out of bounds.
  void validate(const std::string& where) const;
};

/// One synthetic IMU sample with the true biases that were added (for the ground truth).
struct SynthImuSample {
  TimeNs t = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();   // rad/s
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();  // m/s²
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();
};

/// Noise-free specific force and body rate of a kinematic state: accel = R_WRᵀ(a_W − g_W), gyro = w_R.
void ideal_imu(const KinematicState& s, double gravity, Eigen::Vector3d& gyro, Eigen::Vector3d& accel);

/// Draws IMU samples along a trajectory in time order, evolving the biases as random walks.
class ImuSynthesizer {
 public:
  /// Draws the initial biases from `rng` (its own copy is kept: later draws do not touch the caller's rng).
  ImuSynthesizer(const ContinuousTrajectory& trajectory, const ImuSynthOptions& options, Rng rng);
  /// The sample at time t (t must not decrease between calls; the bias walk uses the elapsed time).
  SynthImuSample sample(TimeNs t);
  const Eigen::Vector3d& gyro_bias() const { return b_g_; }
  const Eigen::Vector3d& accel_bias() const { return b_a_; }

 private:
  const ContinuousTrajectory& traj_;
  ImuSynthOptions opt_;
  Rng rng_;
  Eigen::Vector3d b_g_, b_a_;
  std::optional<TimeNs> last_t_;
};

}  // namespace rtslam::sim
