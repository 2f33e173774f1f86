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

int PolicyMapManager::limit(const slam::Map& map) const {
  return opt_.map_size * static_cast<int>(std::max<std::size_t>(1, map.robots().size()));
}

bool PolicyMapManager::has_room(const slam::Map& map, int tangent_size) const {
  return map.state().tangent_used() + tangent_size <= limit(map) &&
         map.state().can_allocate(filter::BlockLayout::euclidean(tangent_size));
}

void PolicyMapManager::manage(slam::Map& map, const slam::Sensor& sensor, long frame, slam::FrameStats& stats) {
  const Eigen::Vector3d p_WS = sensor.pose_in_world(map.state().mean_vector()).p;
  scratch_.clear();
  for (const auto& l : map.landmarks()) scratch_.push_back(l.get());
  double min_index = std::numeric_limits<double>::infinity();
  int ahp = 0;
  for (slam::Landmark* l : scratch_) {
    if (!l->observation_of(sensor)) continue;
    // A landmark is the map's, not the calling sensor's: with several sensors (several cameras, several robots)
    // each observes it with its own counters. The match/inlier judgement removes it only if some sensor judged it
    // bad and none judged it good (one sensor failing to match it from its own viewpoint does not take it from the
    // others), and its last update and last visibility are the latest over all sensors. With one sensor this is
    // the sensor's own judgement.
    bool judged_bad = false, judged_good = false;
    long last_updated = -1, last_visible = -1, updated = 0;
    for (const slam::Observation& ob : l->observations()) {
      const auto& c = ob.counters;
      last_updated = std::max(last_updated, c.last_updated_frame);
      last_visible = std::max(last_visible, c.last_visible_frame);
      updated += c.updated;
      if (c.searched < opt_.min_searches_to_judge) continue;
      const bool bad = c.matched < opt_.min_match_ratio * static_cast<double>(c.searched) ||
                       (c.matched > 0 && c.updated < opt_.min_inlier_ratio * static_cast<double>(c.matched));
      (bad ? judged_bad : judged_good) = true;
    }
    bool remove = judged_bad && !judged_good;
    const long last_update = last_updated >= 0 ? last_updated : l->frame_created;
    if (opt_.policy == MapPolicyOptions::Policy::VisualOdometry && frame - last_update > opt_.forget_after_frames) {
      remove = true;
    }
    if (last_visible < 0) last_visible = l->frame_created;
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
    if (updated > 0 && index < opt_.reparam_threshold) {
      if (slam::reparametrize_to_euclidean(map, *l)) ++stats.reparametrized;
    }
  }
  if (opt_.evict_when_full && map.state().tangent_used() + opt_.evict_rows > limit(map)) {
    evict(map, sensor, frame, stats);
  }
  if (logger_->should_log(spdlog::level::debug)) {
    logger_->debug("frame {}: {} landmarks ({} AHP, smallest linearity index {:.3g}), {} rows used, {} reparametrized, "
                   "{} removed",
                   frame, map.landmarks().size(), ahp, min_index, map.state().tangent_used(), stats.reparametrized,
                   stats.removed);
  }
}

void PolicyMapManager::evict(slam::Map& map, const slam::Sensor& /*sensor*/, long frame, slam::FrameStats& stats) {
  candidates_.clear();
  for (const auto& l : map.landmarks()) {
    // The latest visibility over all sensors: a landmark another sensor sees now is not evicted.
    long last_visible = -1;
    for (const slam::Observation& ob : l->observations()) {
      last_visible = std::max(last_visible, ob.counters.last_visible_frame);
    }
    if (last_visible < 0) last_visible = l->frame_created;
    if (frame - last_visible >= opt_.evict_min_unseen_frames) candidates_.emplace_back(last_visible, l.get());
  }
  // Longest unseen first; ties by id so that the order (and the run) is deterministic.
  std::sort(candidates_.begin(), candidates_.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first < b.first : a.second->id() < b.second->id();
  });
  for (const auto& [last_visible, l] : candidates_) {
    if (map.state().tangent_used() + opt_.evict_rows <= limit(map)) break;
    map.remove_landmark(*l);
    ++stats.removed;
    ++stats.evicted;
  }
}

}  // namespace rtslam::strategies
