#include "rtslam/slam/health.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/models/robots/inertial.hpp"
#include "rtslam/slam/map.hpp"

namespace rtslam::slam {

void HealthOptions::validate() const {
  const std::string w = "health";
  require_bound(lost_after_s > 0.0 && lost_after_s <= 3600.0, w, "lost_after", lost_after_s, "in (0, 3600] s");
  require_bound(min_updated >= 0 && min_updated <= 1000, w, "min_updated", min_updated, "in [0, 1000]");
  require_bound(nis_window >= 1 && nis_window <= 10000, w, "nis_window", nis_window, "in [1, 10000] frames");
  require_bound(nis_min_matches >= 1 && nis_min_matches <= 1000000, w, "nis_min_matches", nis_min_matches,
                "in [1, 1e6]");
  require_bound(max_nis_per_dof > 0.0 && max_nis_per_dof < 1e6, w, "max_nis_per_dof", max_nis_per_dof, "in (0, 1e6)");
  require_bound(max_speed > 0.0 && max_speed <= 1e4, w, "max_speed", max_speed, "in (0, 1e4] m/s");
  require_bound(max_accel_bias > 0.0 && max_accel_bias <= 1e3, w, "max_accel_bias", max_accel_bias, "in (0, 1e3] m/s²");
  require_bound(max_gyro_bias > 0.0 && max_gyro_bias <= 1e3, w, "max_gyro_bias", max_gyro_bias, "in (0, 1e3] rad/s");
  require_bound(grace_s >= 0.0 && grace_s <= 3600.0, w, "grace", grace_s, "in [0, 3600] s");
  require_bound(max_frame_gap_s > 0.0 && max_frame_gap_s <= 3600.0, w, "max_frame_gap", max_frame_gap_s,
                "in (0, 3600] s");
  require_bound(min_consensus >= 0.0 && min_consensus <= 1.0, w, "min_consensus", min_consensus, "in [0, 1]");
  require_bound(low_consensus_after_s > 0.0 && low_consensus_after_s <= 3600.0, w, "low_consensus_after",
                low_consensus_after_s, "in (0, 3600] s");
  require_bound(consensus_min_matches >= 1 && consensus_min_matches <= 1000000, w, "consensus_min_matches",
                consensus_min_matches, "in [1, 1e6]");
}

void read_health(YamlMap m, HealthOptions& o) {
  m.get("enabled", o.enabled);
  m.get("reset", o.reset);
  m.get("lost_after", o.lost_after_s);
  m.get("min_updated", o.min_updated);
  m.get("nis_window", o.nis_window);
  m.get("nis_min_matches", o.nis_min_matches);
  m.get("max_nis_per_dof", o.max_nis_per_dof);
  m.get("max_speed", o.max_speed);
  m.get("max_accel_bias", o.max_accel_bias);
  m.get("max_gyro_bias", o.max_gyro_bias);
  m.get("grace", o.grace_s);
  m.get("max_frame_gap", o.max_frame_gap_s);
  m.get("min_consensus", o.min_consensus);
  m.get("low_consensus_after", o.low_consensus_after_s);
  m.get("consensus_min_matches", o.consensus_min_matches);
  m.finish();
}

YAML::Node health_to_yaml(const HealthOptions& o) {
  YAML::Node n;
  n["enabled"] = o.enabled;
  n["reset"] = o.reset;
  n["lost_after"] = o.lost_after_s;
  n["min_updated"] = o.min_updated;
  n["nis_window"] = o.nis_window;
  n["nis_min_matches"] = o.nis_min_matches;
  n["max_nis_per_dof"] = o.max_nis_per_dof;
  n["max_speed"] = o.max_speed;
  n["max_accel_bias"] = o.max_accel_bias;
  n["max_gyro_bias"] = o.max_gyro_bias;
  n["grace"] = o.grace_s;
  n["max_frame_gap"] = o.max_frame_gap_s;
  n["min_consensus"] = o.min_consensus;
  n["low_consensus_after"] = o.low_consensus_after_s;
  n["consensus_min_matches"] = o.consensus_min_matches;
  return n;
}

const char* to_string(Health h) {
  switch (h) {
    case Health::Ok: return "ok";
    case Health::Lost: return "lost";
    case Health::Diverged: return "diverged";
  }
  return "?";
}

HealthMonitor::HealthMonitor(HealthOptions options)
    : opt_(options), nis_(static_cast<std::size_t>(std::max(1, options.nis_window)) + 1) {
  opt_.validate();
}

void HealthMonitor::restart(TimeNs t) {
  start_t_ = t;
  last_tracked_t_ = t;
  prev_t_ = t;
  nis_.clear();
  low_consensus_since_.reset();
}

HealthMonitor::Verdict HealthMonitor::check(const Map& map, const Robot& robot, const FrameStats& stats) {
  Verdict v;
  if (!opt_.enabled) return v;
  // A datum of an absolute sensor (no landmark to match): only the state's sanity is judged below, and the frame
  // counts neither for the image gaps nor for tracking and NIS.
  const bool tracking = stats.landmark_frame;
  if (tracking && stats.t - prev_t_ > from_seconds(opt_.max_frame_gap_s)) {
    ++gaps_;
    v.note = fmt::format("no image for {:.2f} s", to_seconds(stats.t - prev_t_));
    last_tracked_t_ = stats.t;
    low_consensus_since_.reset();  // a streak is of consecutive frames
  }
  if (tracking) prev_t_ = stats.t;
  const auto x = map.state().mean(robot.block());
  const auto P = map.state().cov(robot.block());
  if (!x.allFinite() || !P.diagonal().allFinite()) {
    v.health = Health::Diverged;
    v.reason = "the robot's estimate is not finite";
    return v;
  }
  // Robot blocks start [p q v ...]: v at ambient offset 7 for every robot model.
  if (x.size() >= 10 && x.segment<3>(7).norm() > opt_.max_speed) {
    v.health = Health::Diverged;
    v.reason = fmt::format("speed {:.1f} m/s above health/max_speed {:.1f}", x.segment<3>(7).norm(), opt_.max_speed);
    return v;
  }
  if (dynamic_cast<const InertialRobot*>(&robot) != nullptr) {
    const double ab = x.segment<3>(models::InertialIndex::kAb).norm();
    const double wb = x.segment<3>(models::InertialIndex::kWb).norm();
    if (ab > opt_.max_accel_bias || wb > opt_.max_gyro_bias) {
      v.health = Health::Diverged;
      v.reason = fmt::format("IMU biases |a_b| = {:.2f} m/s², |w_b| = {:.3f} rad/s beyond health/max_accel_bias "
                             "{:.2f}, max_gyro_bias {:.3f}", ab, wb, opt_.max_accel_bias, opt_.max_gyro_bias);
      return v;
    }
  }
  if (!tracking) return v;
  if (nis_.size() == static_cast<std::size_t>(opt_.nis_window)) nis_.pop_front();
  nis_.push_back(NisFrame{stats.nis, stats.nis_count});
  if (stats.updated >= opt_.min_updated) last_tracked_t_ = stats.t;
  const bool in_grace = stats.t - start_t_ < from_seconds(opt_.grace_s);
  if (in_grace) {
    last_tracked_t_ = std::max(last_tracked_t_, stats.t);
    return v;
  }
  if (stats.t - last_tracked_t_ >= from_seconds(opt_.lost_after_s)) {
    v.health = Health::Lost;
    v.reason = fmt::format("fewer than {} corrections per frame for {:.2f} s (this frame: {} visible, {} searched, "
                           "{} matched, {} updated)", opt_.min_updated, to_seconds(stats.t - last_tracked_t_),
                           stats.visible, stats.searched, stats.matched, stats.updated);
    return v;
  }
  if (nis_.size() == static_cast<std::size_t>(opt_.nis_window)) {
    double sum = 0.0;
    int count = 0;
    for (std::size_t k = 0; k < nis_.size(); ++k) {
      sum += nis_[k].sum;
      count += nis_[k].count;
    }
    if (count >= opt_.nis_min_matches && sum / (2.0 * count) > opt_.max_nis_per_dof) {
      v.health = Health::Diverged;
      v.reason = fmt::format("mean NIS per dof {:.2f} over the last {} frames above health/max_nis_per_dof {:.2f}",
                             sum / (2.0 * count), nis_.size(), opt_.max_nis_per_dof);
      return v;
    }
  }
  // One-point RANSAC's consensus. Judged: frames where it tested a hypothesis with enough matches, its search not
  // cut short by the time budget (a cut support is not a disagreement). The others neither extend nor end a streak,
  // but a streak no judged frame has confirmed for lost_after_s ends (the last healthy state follows again).
  const bool judged = opt_.min_consensus > 0.0 && stats.ransac_max > 0 && !stats.budget_hit &&
                      stats.matched >= opt_.consensus_min_matches;
  if (!judged) {
    if (low_consensus_since_ && stats.t - last_low_consensus_t_ >= from_seconds(opt_.lost_after_s)) {
      low_consensus_since_.reset();
    }
    return v;
  }
  if (stats.ransac_inliers >= opt_.min_consensus * std::min(stats.matched, stats.ransac_max)) {
    low_consensus_since_.reset();
    return v;
  }
  if (!low_consensus_since_) low_consensus_since_ = stats.t;
  last_low_consensus_t_ = stats.t;
  if (stats.t - *low_consensus_since_ >= from_seconds(opt_.low_consensus_after_s)) {
    v.health = Health::Lost;
    v.reason = fmt::format(
        "one-point RANSAC explained fewer than {:.0f} % of the matches in every frame for {:.2f} s "
        "(this frame: {} of {} matched): the matches no longer agree on one motion",
        100.0 * opt_.min_consensus, to_seconds(stats.t - *low_consensus_since_), stats.ransac_inliers, stats.matched);
  }
  return v;
}

}  // namespace rtslam::slam
