#pragma once
// Map-manager policies (RT-SLAM): the map size limit, AHP→Euclidean reparametrization by the linearity index,
// and landmark removal:
//  - Global: keep landmarks; remove those whose search/match record is poor (after `min_searches_to_judge`
//    searches: matched/searched below `min_match_ratio`, or updated/matched below `min_inlier_ratio`) — a landmark
//    that left the view stays for when it comes back (loops close), unless `forget_unseen_after_frames` is set;
//  - VisualOdometry: also forget landmarks not updated (used in a correction) for more than `forget_after_frames`
//    frames: those out of view, and those in view that are no longer matched.
// `forget_unseen_after_frames` (> 0) applies to both policies: landmarks not visible for more than that many frames
// are dropped (for VisualOdometry it only matters when below `forget_after_frames`).
// An AHP landmark that has been used in at least one update becomes Euclidean when its linearity index, seen from
// the sensor, is below `reparam_threshold` (before its first update its covariance is the prior's).
// Both policies make room in a nearly full map (`evict_when_full`): a full map would stop feature initialization and
// leave the camera blind once it turns away from the mapped part of the scene, so when fewer than `evict_rows` rows
// are free, the landmarks out of view the longest (not visible for at least `evict_min_unseen_frames`; ties: the
// lower id) are dropped until `evict_rows` rows are free again, or no such landmark is left.
// The map size counts covariance rows ("state entries", as RT-SLAM's MAP_SIZE): an AHP point takes 7, a
// Euclidean point 3, the robot its own. It is a budget per robot: a map that k robots share (several robots in one
// world, Registry::add_robot_to) holds k × map_size rows, so that each robot keeps as many landmarks as alone (one
// budget for all would halve each robot's map: in the two-robot test the landmarks in each camera's view fell from
// 60-66 to 36-42 and both robots' errors rose above their errors alone). The counters judged are those of the
// sensor `manage` is called for (one camera per map in the pipelines).
#include <memory>

#include <spdlog/logger.h>

#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/map.hpp"

namespace rtslam::strategies {

struct MapPolicyOptions {
  enum class Policy { Global, VisualOdometry };
  Policy policy = Policy::Global;
  int map_size = 500;                 // covariance rows (state entries) for landmarks + robot, per robot in the map
  static constexpr int kMaxMapSize = 10000;  // = filter::StateOptions::kMaxTangentCapacity
  double reparam_threshold = 0.1;     // RT-SLAM REPARAM_TH: convert AHP when the linearity index is below
  int min_searches_to_judge = 10;     // before judging the match ratio
  double min_match_ratio = 0.5;       // matched / searched below this: remove (Global and VO)
  double min_inlier_ratio = 0.5;      // updated / matched below this: remove (inconsistent)
  long forget_after_frames = 60;      // VO: frames without an update before a landmark is dropped
  long forget_unseen_after_frames = 0;  // any policy: drop landmarks not visible for this long (0: never)
  bool evict_when_full = true;        // make room in a nearly full map by dropping the longest-unseen landmarks ...
  long evict_min_unseen_frames = 20;  // ... that have not been visible for at least this many frames ...
  int evict_rows = 70;                // ... until this many rows are free (70: 10 AHP points, RT-SLAM N_INIT)
  void validate() const;
};

class PolicyMapManager final : public slam::MapManager {
 public:
  explicit PolicyMapManager(MapPolicyOptions options);
  bool has_room(const slam::Map& map, int tangent_size) const override;
  void manage(slam::Map& map, const slam::Sensor& sensor, long frame, slam::FrameStats& stats) override;
  const MapPolicyOptions& options() const { return opt_; }
  /// The map's row budget: map_size per robot in the map (at least one).
  int limit(const slam::Map& map) const;

 private:
  MapPolicyOptions opt_;
  void evict(slam::Map& map, const slam::Sensor& sensor, long frame, slam::FrameStats& stats);
  std::vector<slam::Landmark*> scratch_;
  std::vector<std::pair<long, slam::Landmark*>> candidates_;
  std::shared_ptr<spdlog::logger> logger_;
};

}  // namespace rtslam::strategies
