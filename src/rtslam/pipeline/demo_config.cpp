#include "rtslam/pipeline/demo_config.hpp"

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/pipeline/config_common.hpp"

namespace rtslam::pipeline {


void apply_demo_config(const YAML::Node& root, const std::string& where, PointDemoOptions& o) {
  YamlMap top(root, where);
  if (top.has("slam") && !top.has("demo")) {  // an image pipeline's configuration (config/*.yaml, a run's)
    throw ConfigError(fmt::format("{}: an image-pipeline configuration (key 'slam'): run it without --points-demo",
                                  where));
  }
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
  read_motion(top.child("motion"), o.motion);
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
  read_map_policy(top.child("map_manager"), o.map);
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
  root["motion"] = motion_to_yaml(o.motion);
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
  root["map_manager"] = map_policy_to_yaml(o.map);
  return root;
}

}  // namespace rtslam::pipeline
