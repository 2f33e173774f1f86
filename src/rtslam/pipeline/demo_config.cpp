#include "rtslam/pipeline/demo_config.hpp"

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"

namespace rtslam::pipeline {

namespace {
const char* policy_name(strategies::MapPolicyOptions::Policy p) {
  return p == strategies::MapPolicyOptions::Policy::Global ? "global" : "visual_odometry";
}
}  // namespace

void apply_demo_config(const YAML::Node& root, const std::string& where, PointDemoOptions& o) {
  YamlMap top(root, where);
  {
    YamlMap d = top.child("demo");
    d.get("seed", o.seed);
    d.get("duration_s", o.duration_s);
    d.get("rate_hz", o.rate_hz);
    d.get("n_points", o.n_points);
    d.get("sigma_px", o.sigma_px);
    d.get("initial_velocity_std", o.initial_velocity_std);
    d.get("state_capacity", o.state_capacity);
    d.finish();
  }
  {
    YamlMap m = top.child("motion");
    m.get("sigma_v", o.motion.sigma_v);
    m.get("sigma_w", o.motion.sigma_w);
    m.finish();
  }
  {
    YamlMap a = top.child("association");
    auto& ka = o.association;
    a.get("sigma_px", ka.sigma_px);
    a.get("n_sigma", ka.n_sigma);
    a.get("max_updates", ka.max_updates);
    a.get("max_inits", ka.max_inits);
    a.get("gain_recomputations", ka.gain_recomputations);
    a.get("margin_px", ka.margin_px);
    a.get("d_min", ka.prior.d_min);
    YamlMap g = a.child("grid");
    g.get("cells_x", ka.grid.cells_x);
    g.get("cells_y", ka.grid.cells_y);
    g.get("margin_px", ka.grid.margin_px);
    g.finish();
    a.finish();
  }
  {
    YamlMap m = top.child("map_manager");
    auto& mp = o.map;
    std::string policy = policy_name(mp.policy);
    m.get("policy", policy);
    if (policy == "global") {
      mp.policy = strategies::MapPolicyOptions::Policy::Global;
    } else if (policy == "visual_odometry") {
      mp.policy = strategies::MapPolicyOptions::Policy::VisualOdometry;
    } else {
      throw ConfigError(fmt::format("{}: map_manager/policy = '{}' must be global or visual_odometry", where, policy));
    }
    m.get("map_size", mp.map_size);
    m.get("reparam_threshold", mp.reparam_threshold);
    m.get("min_searches_to_judge", mp.min_searches_to_judge);
    m.get("min_match_ratio", mp.min_match_ratio);
    m.get("min_inlier_ratio", mp.min_inlier_ratio);
    m.get("forget_after_frames", mp.forget_after_frames);
    m.get("forget_unseen_after_frames", mp.forget_unseen_after_frames);
    m.finish();
  }
  top.finish();
  try {
    o.validate();
  } catch (const ConfigError& e) {
    throw ConfigError(fmt::format("{}: {}", where, e.what()));
  }
}

PointDemoOptions load_demo_config(const std::string& path) {
  PointDemoOptions o;
  apply_demo_config(load_yaml_file(path), path, o);
  return o;
}

YAML::Node to_yaml(const PointDemoOptions& o) {
  YAML::Node root;
  root["demo"]["seed"] = o.seed;
  root["demo"]["duration_s"] = o.duration_s;
  root["demo"]["rate_hz"] = o.rate_hz;
  root["demo"]["n_points"] = o.n_points;
  root["demo"]["sigma_px"] = o.sigma_px;
  root["demo"]["initial_velocity_std"] = o.initial_velocity_std;
  root["demo"]["state_capacity"] = o.state_capacity;
  root["motion"]["sigma_v"] = o.motion.sigma_v;
  root["motion"]["sigma_w"] = o.motion.sigma_w;
  const auto& ka = o.association;
  root["association"]["sigma_px"] = ka.sigma_px;
  root["association"]["n_sigma"] = ka.n_sigma;
  root["association"]["max_updates"] = ka.max_updates;
  root["association"]["max_inits"] = ka.max_inits;
  root["association"]["gain_recomputations"] = ka.gain_recomputations;
  root["association"]["margin_px"] = ka.margin_px;
  root["association"]["d_min"] = ka.prior.d_min;
  root["association"]["grid"]["cells_x"] = ka.grid.cells_x;
  root["association"]["grid"]["cells_y"] = ka.grid.cells_y;
  root["association"]["grid"]["margin_px"] = ka.grid.margin_px;
  const auto& mp = o.map;
  root["map_manager"]["policy"] = policy_name(mp.policy);
  root["map_manager"]["map_size"] = mp.map_size;
  root["map_manager"]["reparam_threshold"] = mp.reparam_threshold;
  root["map_manager"]["min_searches_to_judge"] = mp.min_searches_to_judge;
  root["map_manager"]["min_match_ratio"] = mp.min_match_ratio;
  root["map_manager"]["min_inlier_ratio"] = mp.min_inlier_ratio;
  root["map_manager"]["forget_after_frames"] = mp.forget_after_frames;
  root["map_manager"]["forget_unseen_after_frames"] = mp.forget_unseen_after_frames;
  return root;
}

}  // namespace rtslam::pipeline
