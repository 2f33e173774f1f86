#include "rtslam/strategies/map_policies.hpp"

#include <algorithm>
#include <limits>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/slam/landmark_init.hpp"

namespace rtslam::strategies {

void MapPolicyOptions::validate() const {
  if (map_size <= 0) throw ConfigError(fmt::format("map_manager: map_size = {} must be > 0", map_size));
  if (!(reparam_threshold >= 0.0)) {
    throw ConfigError(fmt::format("map_manager: reparam_threshold = {} must be >= 0", reparam_threshold));
  }
  if (!(min_match_ratio >= 0.0 && min_match_ratio <= 1.0) || !(min_inlier_ratio >= 0.0 && min_inlier_ratio <= 1.0)) {
    throw ConfigError("map_manager: min_match_ratio and min_inlier_ratio must be in [0, 1]");
  }
  if (forget_after_frames < 1 || forget_unseen_after_frames < 0 || min_searches_to_judge < 1) {
    throw ConfigError("map_manager: forget_after_frames and min_searches_to_judge must be >= 1");
  }
  if (evict_min_unseen_frames < 1) {
    throw ConfigError(fmt::format("map_manager: evict_min_unseen_frames = {} must be >= 1", evict_min_unseen_frames));
  }
  if (evict_rows < 0 || evict_rows > map_size) {
    throw ConfigError(fmt::format("map_manager: evict_rows = {} must be in [0, map_size = {}]", evict_rows, map_size));
  }
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
