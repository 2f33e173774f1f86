#include "rtslam/pipeline/config_common.hpp"

#include <fmt/format.h>

#include "rtslam/core/error.hpp"

namespace rtslam::pipeline {

namespace {
const char* policy_name(strategies::MapPolicyOptions::Policy p) {
  return p == strategies::MapPolicyOptions::Policy::Global ? "global" : "visual_odometry";
}
}  // namespace

void read_motion(YamlMap m, models::ConstantVelocityParams& motion) {
  m.get("sigma_v", motion.sigma_v);
  m.get("sigma_w", motion.sigma_w);
  m.finish();
}

YAML::Node motion_to_yaml(const models::ConstantVelocityParams& motion) {
  YAML::Node n;
  n["sigma_v"] = motion.sigma_v;
  n["sigma_w"] = motion.sigma_w;
  return n;
}

void read_map_policy(YamlMap m, strategies::MapPolicyOptions& mp) {
  std::string policy = policy_name(mp.policy);
  m.get("policy", policy);
  if (policy == "global") {
    mp.policy = strategies::MapPolicyOptions::Policy::Global;
  } else if (policy == "visual_odometry") {
    mp.policy = strategies::MapPolicyOptions::Policy::VisualOdometry;
  } else {
    throw ConfigError(
        fmt::format("{}: policy = '{}' must be global or visual_odometry", m.where(), policy));
  }
  m.get("map_size", mp.map_size);
  m.get("reparam_threshold", mp.reparam_threshold);
  m.get("min_searches_to_judge", mp.min_searches_to_judge);
  m.get("min_match_ratio", mp.min_match_ratio);
  m.get("min_inlier_ratio", mp.min_inlier_ratio);
  m.get("forget_after_frames", mp.forget_after_frames);
  m.get("forget_unseen_after_frames", mp.forget_unseen_after_frames);
  m.get("evict_when_full", mp.evict_when_full);
  m.get("evict_min_unseen_frames", mp.evict_min_unseen_frames);
  m.get("evict_rows", mp.evict_rows);
  m.finish();
}

YAML::Node map_policy_to_yaml(const strategies::MapPolicyOptions& mp) {
  YAML::Node n;
  n["policy"] = policy_name(mp.policy);
  n["map_size"] = mp.map_size;
  n["reparam_threshold"] = mp.reparam_threshold;
  n["min_searches_to_judge"] = mp.min_searches_to_judge;
  n["min_match_ratio"] = mp.min_match_ratio;
  n["min_inlier_ratio"] = mp.min_inlier_ratio;
  n["forget_after_frames"] = mp.forget_after_frames;
  n["forget_unseen_after_frames"] = mp.forget_unseen_after_frames;
  n["evict_when_full"] = mp.evict_when_full;
  n["evict_min_unseen_frames"] = mp.evict_min_unseen_frames;
  n["evict_rows"] = mp.evict_rows;
  return n;
}

}  // namespace rtslam::pipeline
