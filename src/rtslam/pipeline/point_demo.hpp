#pragma once
// The walking skeleton: monocular EKF-SLAM on simulated point measurements with known data association. The scene
// (sim/point_scene.hpp: points on a room's faces, the EuRoC cam0 camera on a hand-held body, pixel noise) makes the
// measurements; this side is the SLAM system given only those measurements, the camera and the start pose: the
// constant-velocity robot, undelayed AHP initialization, reparametrization to Euclidean points, and a policy map
// manager. Everything is seeded: the same options give the same output.
#include <cstdint>
#include <functional>
#include <vector>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/models/robots/constant_velocity.hpp"
#include "rtslam/sim/point_scene.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/strategies/known_association.hpp"
#include "rtslam/strategies/map_policies.hpp"

namespace rtslam::pipeline {

/// RT-SLAM's association defaults, with the demo room's inverse-depth prior (d_min = 1 m, see below).
strategies::KnownAssociationOptions demo_association_defaults();

/// RT-SLAM's global map policy, plus: landmarks not visible for 300 frames (10 s at 30 Hz) are dropped, so the
/// bounded map keeps room for what the camera sees now.
strategies::MapPolicyOptions demo_map_defaults();

/// The demo's options: the scene's (seed to sigma_px, see sim::PointSceneOptions) and the filter's.
struct PointDemoOptions {
  std::uint64_t seed = 1;
  double duration_s = 30.0;
  double rate_hz = 30.0;
  int n_points = 500;
  Eigen::Vector3d room_min{-4.0, -3.0, 0.0};  // m, W (z up)
  Eigen::Vector3d room_max{4.0, 3.0, 3.0};
  double sigma_px = 1.0;                       // pixel noise of the simulation (std, px)
  double initial_velocity_std = 0.5;           // m/s and rad/s, the filter's prior on v and ω
  models::ConstantVelocityParams motion;       // σ_v, σ_ω (RT-SLAM defaults 2, 2)
  // The demo room keeps every surface at least 1.3 m from the camera (floor and ceiling, 1.5 m ± 0.15 m away), so
  // its inverse-depth prior uses d_min = 1 m instead of RT-SLAM's hand-held 0.5 m: the prior then covers depths
  // [1 m, ∞) at 2σ, as the scene requires (see docs/configuration.md on choosing d_min).
  strategies::KnownAssociationOptions association = demo_association_defaults();
  strategies::MapPolicyOptions map = demo_map_defaults();
  int state_capacity = 600;                    // covariance rows of the filter's storage
  void validate() const;
  /// The scene these options describe (measurements within association.margin_px of the border are not made).
  sim::PointSceneOptions scene() const;
};

struct PointDemoResult {
  Trajectory estimate;     // T_WR per frame, with the 6x6 pose covariance
  std::vector<slam::FrameStats> frames;
  int landmarks_final = 0;
  int landmarks_created = 0;
  int euclidean_final = 0;
};

/// Runs the filter of `options` on every frame of `scene` (made from options.scene(); its truth is the caller's, for
/// scoring afterwards); `on_frame(i, n)` is called after each frame (progress display), may be empty.
PointDemoResult run_point_demo(const PointDemoOptions& options, sim::PointScene& scene,
                               const std::function<void(int, int)>& on_frame = {});

}  // namespace rtslam::pipeline
