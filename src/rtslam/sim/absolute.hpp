#pragma once
// Simulated absolute sensors: a GPS-like position of an antenna and a motion-capture pose of a marker body, both
// measured from the ground-truth trajectory in the simulator's world frame (z up: the frame the fixes are
// expressed in), at their own rate, with white Gaussian noise drawn from a fixed seed.
//   gps:   {enabled, rate_hz, sigma, lever_arm}             z = p_WR + R_WR p_RA + n,  n ~ N(0, σ² I) (m)
//   mocap: {enabled, rate_hz, sigma, sigma_deg, lever_arm, rotation_deg}
//          z = T_WR T_RM ⊕ n: p + n_p (σ, m), q ⊗ Exp(n_θ) (σ_deg per axis)
// Fix times: t0 + k / rate over the sequence (the first at the first sample).
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/yaml.hpp"
#include "rtslam/io/source.hpp"
#include "rtslam/sim/trajectory.hpp"

namespace rtslam::sim {

struct AbsoluteSimOptions {
  bool enabled = false;
  double rate_hz = 5.0;
  double sigma_m = 0.5;      // m, per axis
  double sigma_deg = 0.0;    // deg per axis (mocap only)
  Eigen::Vector3d lever_arm = Eigen::Vector3d::Zero();     // m: p_RA / p_RM in R
  Eigen::Vector3d rotation_deg = Eigen::Vector3d::Zero();  // deg: R_RM as a rotation vector (mocap only)
  /// Reads `gps` (pose = false) or `mocap` keys; strict.
  void read(YamlMap& m, bool pose);
  void validate(const std::string& where) const;
};

/// Position fixes of the antenna over [t0, t1] (seeded).
std::vector<io::PositionSample> make_position_fixes(const ContinuousTrajectory& traj, TimeNs t0, TimeNs t1,
                                                    const AbsoluteSimOptions& o, std::uint64_t seed);
/// Marker-body poses over [t0, t1] (seeded).
std::vector<io::PoseSample> make_pose_fixes(const ContinuousTrajectory& traj, TimeNs t0, TimeNs t1,
                                            const AbsoluteSimOptions& o, std::uint64_t seed);

}  // namespace rtslam::sim
