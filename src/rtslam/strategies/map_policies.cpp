#include "rtslam/strategies/map_policies.hpp"

#include <algorithm>
#include <limits>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/slam/landmark_init.hpp"

namespace rtslam::strategies {

void MapPolicyOptions::validate() const {
  const std::string w = "map_manager";
  require_bound(map_size > 0 && map_size <= kMaxMapSize, w, "map_size", map_size,
                fmt::format("in [1, {}] covariance rows", kMaxMapSize));
  require_bound(reparam_threshold >= 0.0 && reparam_threshold <= 10.0, w, "reparam_threshold", reparam_threshold,
                "in [0, 10]");
  require_bound(min_match_ratio >= 0.0 && min_match_ratio <= 1.0, w, "min_match_ratio", min_match_ratio, "in [0, 1]");
  require_bound(min_inlier_ratio >= 0.0 && min_inlier_ratio <= 1.0, w, "min_inlier_ratio", min_inlier_ratio,
                "in [0, 1]");
  constexpr int kMaxFrames = 1'000'000;
  const std::string frames = fmt::format("in [1, {}] frames", kMaxFrames);
  require_bound(min_searches_to_judge >= 1 && min_searches_to_judge <= kMaxFrames, w, "min_searches_to_judge",
                min_searches_to_judge, frames);
  require_bound(forget_after_frames >= 1 && forget_after_frames <= kMaxFrames, w, "forget_after_frames",
                forget_after_frames, frames);
  require_bound(forget_unseen_after_frames >= 0 && forget_unseen_after_frames <= kMaxFrames, w,
                "forget_unseen_after_frames", forget_unseen_after_frames,
                fmt::format("in [0, {}] frames (0: never)", kMaxFrames));
  require_bound(evict_min_unseen_frames >= 1 && evict_min_unseen_frames <= kMaxFrames, w, "evict_min_unseen_frames",
                evict_min_unseen_frames, frames);
  require_bound(evict_rows >= 0 && evict_rows <= map_size, w, "evict_rows", evict_rows, "in [0, map_size]");
}

PolicyMapManager::PolicyMapManager(MapPolicyOptions options) : opt_(options) {
  opt_.validate();
  scratch_.reserve(256);
  candidates_.reserve(256);
  logger_ = logger("map");
}

bool PolicyMapManager::has_room(const slam::Map& map, int tangent_size) const {
  return map.state().tangent_used() + tangent_size <= opt_.map_size &&
         map.state().can_allocate(filter::BlockLayout::euclidean(tangent_size));
}

void PolicyMapManager::manage(slam::Map& map, const slam::Sensor& sensor, long frame, slam::FrameStats& stats) {
  const Eigen::Vector3d p_WS = sensor.pose_in_world(map.state().mean_vector()).p;
  scratch_.clear();
  for (const auto& l : map.landmarks()) scratch_.push_back(l.get());
  double min_index = std::numeric_limits<double>::infinity();
  int ahp = 0;
  for (slam::Landmark* l : scratch_) {
    const slam::Observation* o = l->observation_of(sensor);
    if (!o) continue;
    const auto& c = o->counters;
    bool remove = false;
    if (c.searched >= opt_.min_searches_to_judge) {
      if (c.matched < opt_.min_match_ratio * static_cast<double>(c.searched)) remove = true;
      if (c.matched > 0 && c.updated < opt_.min_inlier_ratio * static_cast<double>(c.matched)) remove = true;
    }
    const long last_update = c.last_updated_frame >= 0 ? c.last_updated_frame : l->frame_created;
    if (opt_.policy == MapPolicyOptions::Policy::VisualOdometry && frame - last_update > opt_.forget_after_frames) {
      remove = true;
    }
    const long last_visible = c.last_visible_frame >= 0 ? c.last_visible_frame : l->frame_created;
    if (opt_.forget_unseen_after_frames > 0 && frame - last_visible > opt_.forget_unseen_after_frames) remove = true;
    if (remove) {
      map.remove_landmark(*l);
      ++stats.removed;
      continue;
    }
    if (l->type() != slam::LandmarkType::AhpPoint) continue;
    ++ahp;
    const double index = slam::linearity_index(map, *l, p_WS);
    min_index = std::min(min_index, index);
    if (c.updated > 0 && index < opt_.reparam_threshold) {
      if (slam::reparametrize_to_euclidean(map, *l)) ++stats.reparametrized;
    }
  }
  if (opt_.evict_when_full && map.state().tangent_used() + opt_.evict_rows > opt_.map_size) {
    evict(map, sensor, frame, stats);
  }
  if (logger_->should_log(spdlog::level::debug)) {
    logger_->debug("frame {}: {} landmarks ({} AHP, smallest linearity index {:.3g}), {} rows used, {} reparametrized, "
                   "{} removed",
                   frame, map.landmarks().size(), ahp, min_index, map.state().tangent_used(), stats.reparametrized,
                   stats.removed);
  }
}

void PolicyMapManager::evict(slam::Map& map, const slam::Sensor& sensor, long frame, slam::FrameStats& stats) {
  candidates_.clear();
  for (const auto& l : map.landmarks()) {
    const slam::Observation* o = l->observation_of(sensor);
    const long last_visible = o && o->counters.last_visible_frame >= 0 ? o->counters.last_visible_frame
                                                                       : l->frame_created;
    if (frame - last_visible >= opt_.evict_min_unseen_frames) candidates_.emplace_back(last_visible, l.get());
  }
  // Longest unseen first; ties by id so that the order (and the run) is deterministic.
  std::sort(candidates_.begin(), candidates_.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : a.second->id() < b.second->id();
  });
  for (const auto& [last_visible, l] : candidates_) {
    if (map.state().tangent_used() + opt_.evict_rows <= opt_.map_size) break;
    map.remove_landmark(*l);
    ++stats.removed;
    ++stats.evicted;
  }
}

}  // namespace rtslam::strategies
