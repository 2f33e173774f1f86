#pragma once
// Odometry synthesis from a continuous trajectory (the simulator counterpart of models/robots/odometry.hpp): at
// rate_hz, the increment of the robot frame between two readings, u = [dp dθ] with T_{k}⁻¹ T_{k+1} = (Exp(dθ), dp)
// (both in R at the first reading), plus white noise drawn with the model's covariance at the true increment:
//   n ~ N(0, diag((σ_p² dt + k_p² |dp|) I₃, (σ_θ² dt + k_θ² |dθ|) I₃)).
// The filter's default odometry noise (slam `odometry:` keys) is the same model with the same defaults.
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/random.hpp"
#include "rtslam/core/time.hpp"
#include "rtslam/models/robots/odometry.hpp"
#include "rtslam/sim/trajectory.hpp"

namespace rtslam {
class YamlMap;
}

namespace rtslam::sim {

struct OdometrySynthOptions {
  bool enabled = false;
  double rate_hz = 50.0;          // readings per second, in (0, 1000]
  models::OdometryParams noise;   // sigma_p, sigma_theta, k_p, k_theta (models/robots/odometry.hpp)
  bool noise_enabled = true;      // false: exact increments
  /// Reads enabled, rate_hz, sigma_p, sigma_theta, k_p, k_theta, noise from a mapping (a present mapping enables
  /// the odometry unless it says enabled: false); unknown keys are left for the caller's finish().
  void read(YamlMap& map);
  /// Throws ConfigError naming `where` and the key if a value is out of bounds.
  void validate(const std::string& where) const;
};

/// One odometry reading: the increment over (t_from, t].
struct SynthOdometry {
  TimeNs t_from = 0, t = 0;
  Eigen::Vector3d dp = Eigen::Vector3d::Zero();
  Eigen::Vector3d dtheta = Eigen::Vector3d::Zero();
};

/// The readings at t0 + k / rate_hz (k >= 1) up to t1, each the increment since the previous one (the first since
/// t0), noise drawn from `rng`.
std::vector<SynthOdometry> synthesize_odometry(const ContinuousTrajectory& trajectory, TimeNs t0, TimeNs t1,
                                               const OdometrySynthOptions& options, Rng rng);

}  // namespace rtslam::sim
