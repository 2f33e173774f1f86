#pragma once
// Helpers shared by the eval tests: random poses and smooth synthetic trajectories (fixed seeds).
#include <cmath>

#include <Eigen/Geometry>

#include "rtslam/core/random.hpp"
#include "rtslam/core/trajectory.hpp"
#include "rtslam/eval/geometry.hpp"

namespace rtslam::eval::test {

inline Eigen::Quaterniond random_quaternion(Rng& rng) {
  Eigen::Vector4d v(randn(rng), randn(rng), randn(rng), randn(rng));
  v.normalize();
  return Eigen::Quaterniond(v[0], v[1], v[2], v[3]);
}

inline Eigen::Quaterniond exp_q(const Eigen::Vector3d& theta) {
  const double a = theta.norm();
  if (a < 1e-12) return Eigen::Quaterniond(1.0, 0.5 * theta.x(), 0.5 * theta.y(), 0.5 * theta.z()).normalized();
  return Eigen::Quaterniond(Eigen::AngleAxisd(a, theta / a));
}

/// A smooth hand-held-like 3D trajectory: n poses at `rate_hz`, starting at t0.
inline Trajectory wavy_trajectory(int n, double rate_hz = 20.0, TimeNs t0 = 1'000'000'000) {
  Trajectory traj;
  for (int i = 0; i < n; ++i) {
    const double t = i / rate_hz;
    StampedPose p;
    p.t = t0 + from_seconds(t);
    p.p_WR = Eigen::Vector3d(1.5 * std::sin(0.7 * t) + 0.3 * t, 1.0 * std::cos(0.5 * t), 0.4 * std::sin(1.3 * t));
    p.q_WR = exp_q(Eigen::Vector3d(0.3 * std::sin(0.9 * t), 0.2 * std::cos(1.1 * t), 0.8 * t));
    traj.poses.push_back(p);
  }
  return traj;
}

/// A random similarity transform with scale in [0.5, 2].
inline Sim3 random_sim3(Rng& rng, bool with_scale) {
  Sim3 S;
  S.R = random_quaternion(rng).toRotationMatrix();
  S.t = randn_vec<3>(rng, 3.0);
  S.s = with_scale ? std::exp(randu(rng, std::log(0.5), std::log(2.0))) : 1.0;
  return S;
}

}  // namespace rtslam::eval::test
