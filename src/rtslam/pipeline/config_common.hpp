#pragma once
// YAML sections shared by every pipeline configuration (the demo's and the image pipeline's): the
// constant-velocity motion model (`motion`) and the map manager (`map_manager`). Strict: unknown keys and bad
// values are ConfigErrors naming the file and key.
#include <string>

#include <yaml-cpp/yaml.h>

#include "rtslam/core/yaml.hpp"
#include "rtslam/models/robots/constant_velocity.hpp"
#include "rtslam/models/robots/odometry.hpp"
#include "rtslam/slam/odometry_robot.hpp"
#include "rtslam/strategies/map_policies.hpp"

namespace rtslam::pipeline {

struct ImageSlamOptions;

/// The upper bounds of the `slam` and `simulation` keys of ImageSlamOptions (its validate() checks the lower
/// ones): ConfigError "slam: state_capacity = 100000 must be in [100, 10000] covariance rows". Called from
/// ImageSlamOptions::validate().
void validate_slam_bounds(const ImageSlamOptions& o);

/// motion: {sigma_v, sigma_w}
void read_motion(YamlMap section, models::ConstantVelocityParams& motion);
YAML::Node motion_to_yaml(const models::ConstantVelocityParams& motion);

/// odometry: {sigma_p, sigma_theta, k_p, k_theta} (odometry robot; bounds in models::OdometryParams::validate) and
/// {rescale, rescale_window, rescale_max_se, rescale_min_z} (slam::OdometryScaleOptions; bounds in
/// ImageSlamOptions::validate)
void read_odometry(YamlMap section, models::OdometryParams& odometry, std::string& rescale,
                   slam::OdometryScaleOptions& scale);
YAML::Node odometry_to_yaml(const models::OdometryParams& odometry, const std::string& rescale,
                            const slam::OdometryScaleOptions& scale);

/// map_manager: {policy: global|visual_odometry, map_size, reparam_threshold, min_searches_to_judge,
///               min_match_ratio, min_inlier_ratio, forget_after_frames, forget_unseen_after_frames}
void read_map_policy(YamlMap section, strategies::MapPolicyOptions& map);
YAML::Node map_policy_to_yaml(const strategies::MapPolicyOptions& map);

}  // namespace rtslam::pipeline
