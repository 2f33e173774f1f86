#pragma once
// Sensor poses and rays for the landmark and robot Jacobian tests: identity, near-identity (below and above the
// small-angle threshold), random, and rotations by π (the degenerate points of the orientation parametrization).
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/random.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::models::test_samples {

inline std::vector<math::Pose> sample_poses(std::uint64_t seed) {
  Rng rng(seed);
  std::vector<math::Pose> out;
  out.push_back(math::Pose::identity());
  out.push_back({math::exp_so3(Eigen::Vector3d(1e-10, -2e-10, 5e-11)), Eigen::Vector3d(1e-9, 0.0, -1e-9)});
  out.push_back({math::exp_so3(Eigen::Vector3d(1e-5, 3e-5, -2e-5)), Eigen::Vector3d(0.01, -0.02, 0.0)});
  out.push_back({math::exp_so3(Eigen::Vector3d(M_PI, 0.0, 0.0)), Eigen::Vector3d(1.0, 2.0, -0.5)});
  out.push_back({math::exp_so3(Eigen::Vector3d(1.0, -2.0, 0.5).normalized() * M_PI), Eigen::Vector3d(-3.0, 0.2, 1.0)});
  for (int i = 0; i < 8; ++i) out.push_back({math::exp_so3(randn_vec<3>(rng, 1.5)), randn_vec<3>(rng, 3.0)});
  return out;
}

/// Rays in S: on the optical axis, tiny angles off it, grazing, arbitrary scale, random.
inline std::vector<Eigen::Vector3d> sample_rays(std::uint64_t seed) {
  Rng rng(seed);
  std::vector<Eigen::Vector3d> out = {Eigen::Vector3d(0, 0, 1),          Eigen::Vector3d(1e-9, -1e-9, 1),
                                      Eigen::Vector3d(0.3, -0.2, 1),     Eigen::Vector3d(50.0, 1.0, 1),
                                      Eigen::Vector3d(0.02, 0.01, 1e-3), Eigen::Vector3d(-2.0, 3.0, 7.0)};
  for (int i = 0; i < 4; ++i) out.push_back(randn_vec<3>(rng, 1.0) + Eigen::Vector3d(0, 0, 2.0));
  return out;
}

}  // namespace rtslam::models::test_samples
