#include "rtslam/pipeline/config_common.hpp"

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/filter/state.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/pipeline/image_slam.hpp"

namespace rtslam::pipeline {

namespace {
const char* policy_name(strategies::MapPolicyOptions::Policy p) {
  return p == strategies::MapPolicyOptions::Policy::Global ? "global" : "visual_odometry";
}
}  // namespace

void validate_slam_bounds(const ImageSlamOptions& o) {
  const std::string w = "slam";
  constexpr int kMaxCapacity = filter::StateOptions::kMaxTangentCapacity;
  require_bound(o.state_capacity >= 100 && o.state_capacity <= kMaxCapacity, w, "state_capacity", o.state_capacity,
                fmt::format("in [100, {}] covariance rows (a {}-row covariance takes {:.0f} MB)", kMaxCapacity,
                            kMaxCapacity, 8e-6 * kMaxCapacity * kMaxCapacity));
  require_bound(o.initial_velocity_std > 0.0 && o.initial_velocity_std <= 100.0, w, "initial_velocity_std",
                o.initial_velocity_std, "in (0, 100] m/s, rad/s");
  require_bound(o.max_frames >= 0 && o.max_frames <= 1'000'000'000, w, "max_frames", o.max_frames,
                "in [0, 1e9] (0: all)");
  require_bound(o.camera >= 0 && o.camera <= io::DatasetOptions::kMaxCameraIndex, w, "camera", o.camera,
                fmt::format("in [0, {}]", io::DatasetOptions::kMaxCameraIndex));
  require_bound(o.rate_hz == 0.0 || (o.rate_hz >= io::DatasetOptions::kMinRateHz &&
                                     o.rate_hz <= io::DatasetOptions::kMaxRateHz),
                w, "rate_hz", o.rate_hz,
                fmt::format("0 (the dataset's) or in [{:g}, {:g}] Hz", io::DatasetOptions::kMinRateHz,
                            io::DatasetOptions::kMaxRateHz));
  require_bound(o.overlay_frame >= -1 && o.overlay_frame <= 1'000'000'000, w, "overlay_frame", o.overlay_frame,
                "in [-1, 1e9] (-1: none)");
  require_bound(o.sim_duration_s >= 0.0 && o.sim_duration_s <= 86400.0, "simulation", "duration", o.sim_duration_s,
                "in [0, 86400] s (0: the preset's)");
}

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

void read_odometry(YamlMap m, models::OdometryParams& odometry, std::string& rescale,
                   slam::OdometryScaleOptions& scale) {
  m.get("sigma_p", odometry.sigma_p);
  m.get("sigma_theta", odometry.sigma_theta);
  m.get("k_p", odometry.k_p);
  m.get("k_theta", odometry.k_theta);
  m.get("rescale", rescale);
  m.get("rescale_window", scale.window_m);
  m.get("rescale_max_se", scale.max_se);
  m.get("rescale_min_z", scale.min_z);
  m.finish();
}

YAML::Node odometry_to_yaml(const models::OdometryParams& odometry, const std::string& rescale,
                            const slam::OdometryScaleOptions& scale) {
  YAML::Node n;
  n["sigma_p"] = odometry.sigma_p;
  n["sigma_theta"] = odometry.sigma_theta;
  n["k_p"] = odometry.k_p;
  n["k_theta"] = odometry.k_theta;
  n["rescale"] = rescale;
  n["rescale_window"] = scale.window_m;
  n["rescale_max_se"] = scale.max_se;
  n["rescale_min_z"] = scale.min_z;
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
