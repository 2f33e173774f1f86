#pragma once
// YAML configuration of the built-in demo (`rtslam run` without a dataset). Every key is optional (defaults are
// RT-SLAM's), unknown keys are errors naming the key; `to_yaml` writes the effective configuration, which
// `--config` reads back to reproduce a run. Layout:
//   demo:        {seed, duration_s, rate_hz, n_points, sigma_px, initial_velocity_std, state_capacity}
//   motion:      {sigma_v, sigma_w}
//   association: {sigma_px, n_sigma, max_updates, max_inits, gain_recomputations, margin_px, d_min,
//                 grid: {cells_x, cells_y, margin_px}}
//   map_manager: {policy: global|visual_odometry, map_size, reparam_threshold, min_searches_to_judge,
//                 min_match_ratio, min_inlier_ratio, forget_after_frames, forget_unseen_after_frames}
#include <string>

#include <yaml-cpp/yaml.h>

#include "rtslam/pipeline/point_demo.hpp"

namespace rtslam::pipeline {

/// Reads a configuration file over the defaults; throws IoError/ConfigError naming the file and key.
PointDemoOptions load_demo_config(const std::string& path);
/// Applies a parsed YAML document (`where` names it in errors) over `options`.
void apply_demo_config(const YAML::Node& root, const std::string& where, PointDemoOptions& options);
YAML::Node to_yaml(const PointDemoOptions& options);

}  // namespace rtslam::pipeline
