#pragma once
// Monocular EKF-SLAM on real images (paper, sections 3 and 4.1): a System built from an io::Dataset and YAML
// options — one constant-velocity robot carrying the dataset's camera 0 (intrinsics, distortion and T_RS from the
// Rig), the active-search / one-point RANSAC image data manager, the policy map manager. IMU samples are ignored.
// The first robot pose is, in this order: the known-landmark set's initial state (its points then fix scale and
// frame, see known_landmarks.hpp), the ground truth's at the first image (so outputs compare directly), identity;
// without known landmarks it has zero covariance (the gauge). Seeded: the same options and data give
// the same output.
//
// YAML layout (every key optional, unknown keys are errors naming the key; docs/configuration.md):
//   slam:        {seed, initial_velocity_std, state_capacity, max_frames, camera, init_from_groundtruth, rate_hz,
//                 known_landmarks, known_landmarks_convention, overlay_frame, overlay_path}
//   motion:      {sigma_v, sigma_w}
//   search:      see strategies::ActiveSearchOptions::from_yaml
//   map_manager: {policy: global|visual_odometry, map_size, reparam_threshold, min_searches_to_judge,
//                 min_match_ratio, min_inlier_ratio, forget_after_frames, forget_unseen_after_frames}
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/models/robots/constant_velocity.hpp"
#include "rtslam/models/sensors/pinhole_camera.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/strategies/active_search.hpp"
#include "rtslam/strategies/map_policies.hpp"

namespace rtslam::pipeline {

struct ImageSlamOptions {
  std::uint64_t seed = 1;
  double initial_velocity_std = 0.5;  // m/s and rad/s: prior std of v and ω (RT-SLAM)
  int state_capacity = 600;           // covariance rows of the filter storage (>= map_manager.map_size)
  int max_frames = 0;                 // stop after this many images (0: all)
  int camera = 0;                     // index in the Rig
  bool init_from_groundtruth = true;  // first pose from the ground truth when there is one
  double rate_hz = 0.0;               // image rate for image folders without timestamps (0: the dataset's)
  std::string known_landmarks;        // folder of a known-landmark set (known_landmarks.hpp); empty: none
  std::string known_landmarks_convention = "robot";  // that set's state: robot (as is) | scenelib (converted)
  int overlay_frame = -1;             // write a PNG overlay of this image (0-based; -1: none) ...
  std::string overlay_path;           // ... to this file: 3σ search ellipses (blue), matches (green: updated,
                                      // yellow: RANSAC inlier, red: matched but rejected), new landmarks not drawn
  models::ConstantVelocityParams motion;
  strategies::ActiveSearchOptions search;
  strategies::MapPolicyOptions map;
  void validate() const;
};

/// Reads a configuration file over the defaults; throws IoError/ConfigError naming the file and key.
ImageSlamOptions load_image_slam_config(const std::string& path);
void apply_image_slam_config(const YAML::Node& root, const std::string& where, ImageSlamOptions& options);
YAML::Node to_yaml(const ImageSlamOptions& options);

/// io::DistortionModel → models::CameraIntrinsics of one calibrated camera (throws ConfigError if unsupported).
models::CameraIntrinsics to_intrinsics(const io::CameraCalibration& cam);

struct ImageSlamResult {
  Trajectory estimate;  // T_WR per image, with the 6x6 pose covariance
  std::vector<slam::FrameStats> frames;
  int landmarks_final = 0;
  int landmarks_created = 0;
  int euclidean_final = 0;
  int known_landmarks = 0;                      // known landmarks added at the first frame
  std::vector<int> landmark_ids;                // final map
  std::vector<Eigen::Vector3d> landmark_positions;
  std::vector<Eigen::Matrix3d> landmark_covariances;  // of the position (AHP: through J_p_L)
  std::vector<double> landmark_depths;          // distance from the final camera position
};

/// Runs the pipeline over the dataset's images. `on_frame(done, total)` after each image (total 0 if unknown).
ImageSlamResult run_image_slam(io::Dataset& dataset, const ImageSlamOptions& options,
                               const std::function<void(int, int)>& on_frame = {});

}  // namespace rtslam::pipeline
