#pragma once
// Map-manager policies (RT-SLAM): the map size limit, AHP→Euclidean reparametrization by the linearity index,
// and landmark removal:
//  - Global: keep landmarks; remove those whose search/match record is poor (match ratio below a bound after
//    enough searches) — a landmark that left the view stays for when it comes back (loops close);
//  - VisualOdometry: also forget landmarks not observed for `forget_after_frames` frames.
// The map size counts covariance rows ("state entries", as RT-SLAM's MAP_SIZE): an AHP point takes 7, a
// Euclidean point 3, the robot its own.
#include <memory>

#include <spdlog/logger.h>

#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/map.hpp"

namespace rtslam::strategies {

struct MapPolicyOptions {
  enum class Policy { Global, VisualOdometry };
  Policy policy = Policy::Global;
  int map_size = 500;                 // covariance rows (state entries) for landmarks + robots
  double reparam_threshold = 0.1;     // RT-SLAM REPARAM_TH: convert AHP when the linearity index is below
  int min_searches_to_judge = 10;     // before judging the match ratio
  double min_match_ratio = 0.5;       // matched / searched below this: remove (Global and VO)
  double min_inlier_ratio = 0.5;      // updated / matched below this: remove (inconsistent)
  long forget_after_frames = 60;      // VO: frames without an update before a landmark is dropped
  long forget_unseen_after_frames = 0;  // Global: drop landmarks not visible for this long (0: never)
  void validate() const;
};

class PolicyMapManager final : public slam::MapManager {
 public:
  explicit PolicyMapManager(MapPolicyOptions options);
  bool has_room(const slam::Map& map, int tangent_size) const override;
  void manage(slam::Map& map, const slam::Sensor& sensor, long frame, slam::FrameStats& stats) override;
  const MapPolicyOptions& options() const { return opt_; }

 private:
  MapPolicyOptions opt_;
  std::vector<slam::Landmark*> scratch_;
  std::shared_ptr<spdlog::logger> logger_;
};

}  // namespace rtslam::strategies
