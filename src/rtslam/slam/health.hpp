#pragma once
// The health monitor (issue "Inertial SLAM that holds on real IMU data"): after every processed frame it judges
// whether the filter still tracks, from what the run itself sees (no reference trajectory):
//  - non-finite estimate: diverged at once;
//  - implausible robot state: speed above max_speed, accelerometer or gyro bias beyond their bounds (inertial
//    robots): diverged;
//  - tracking lost: fewer than min_updated corrections per frame during lost_after_s (search regions too large to
//    search, every match gated out or refused, no landmark in view);
//  - innovations out of statistics: the mean normalized innovation squared per measurement dof of the matched
//    observations (at their first prediction of the frame, FrameStats::nis) over the last nis_window frames above
//    max_nis_per_dof (a consistent filter gives 1; matches only come from inside the n_sigma ellipse, so the mean
//    cannot exceed n_sigma²/2: a mean near that bound means every match sits at the edge of its ellipse).
//  - no consensus: one-point RANSAC's best hypothesis explained fewer than min_consensus of the frame's matches (at
//    most max_updates_ransac of them: FrameStats::ransac_max) in every judged frame (ransac_max > 0, at least
//    consensus_min_matches matches, the search's time budget not hit) for low_consensus_after_s: lost (checked
//    after the NIS). Frames not judged neither extend nor end a streak, but one that no judged frame confirms for
//    lost_after_s ends, and so does one an image gap interrupts. The matches still pass their gates one by one,
//    but no single motion explains them; a filter in that state has been seen to turn its attitude by 13° in 1.5 s
//    with a NIS per dof near 1 (the simulator's `ground` preset, seed 8, odometry robot). In a healthy run such
//    frames come alone or two in a row (docs/configuration.md "health": 22 sequences, 18 more held out). While a
//    streak of them lasts, the robot's last healthy state (the one a reset restarts from) is not updated: suspect().
// The verdicts of "lost", NIS and consensus wait grace_s after a (re)start, while the map is being built. A gap of more
// than max_frame_gap_s between two frames (an image blackout) is noted, and the lost timer starts again at the frame
// after it: the filter, carried by its motion model or IMU through the gap, gets lost_after_s to find its
// landmarks again before it is declared lost. Data of absolute sensors (FrameStats::landmark_frame false: a GPS
// fix) are judged for the state's sanity only: they match no landmark, so they count neither as tracked nor as
// lost, nor as image frames. The caller decides what to do with a verdict (the pipeline re-initializes the robot from
// its last healthy state when reset is on).
#include <optional>
#include <string>

#include "rtslam/core/ring_buffer.hpp"
#include "rtslam/core/time.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/slam/managers.hpp"

namespace rtslam::slam {

class Map;
class Robot;

struct HealthOptions {
  bool enabled = true;
  bool reset = true;              // re-initialize the robot and the map on a verdict (false: report only)
  double lost_after_s = 0.5;      // s with fewer than min_updated corrections per frame
  int min_updated = 3;
  int nis_window = 20;            // frames
  int nis_min_matches = 30;       // matches needed in the window to judge the NIS
  double max_nis_per_dof = 3.5;   // mean NIS per measurement dof over the window
  double max_speed = 50.0;        // m/s
  double max_accel_bias = 3.0;    // m/s² (norm)
  double max_gyro_bias = 1.0;     // rad/s (norm)
  double grace_s = 1.0;           // after a (re)start: no lost/NIS verdict
  double max_frame_gap_s = 0.5;   // a longer gap between frames is noted (image blackout)
  double min_consensus = 0.35;    // fraction of the matches one-point RANSAC must explain (0: not judged)
  double low_consensus_after_s = 0.25;  // s of frames below min_consensus before "lost"
  int consensus_min_matches = 10;       // frames with fewer matches are not judged for consensus
  void validate() const;
};
/// health: {enabled, reset, lost_after, min_updated, nis_window, nis_min_matches, max_nis_per_dof, max_speed,
/// max_accel_bias, max_gyro_bias, grace, max_frame_gap, min_consensus, low_consensus_after, consensus_min_matches}
/// (times in s).
void read_health(YamlMap section, HealthOptions& o);
YAML::Node health_to_yaml(const HealthOptions& o);

enum class Health { Ok = 0, Lost = 1, Diverged = 2 };
const char* to_string(Health h);

class HealthMonitor {
 public:
  explicit HealthMonitor(HealthOptions options);
  struct Verdict {
    Health health = Health::Ok;
    std::string reason;  // empty when Ok
    std::string note;    // an event worth a log line that is not a verdict (an image gap)
  };
  /// Judges the state after a processed frame (stats of that frame).
  Verdict check(const Map& map, const Robot& robot, const FrameStats& stats);
  /// Forget the history: the robot (re)starts at t.
  void restart(TimeNs t);
  const HealthOptions& options() const { return opt_; }
  int frame_gaps() const { return gaps_; }
  /// In a streak of low-consensus frames (not yet long enough for a verdict): the state is not to be trusted as the
  /// last healthy one.
  bool suspect() const { return low_consensus_since_.has_value(); }

 private:
  HealthOptions opt_;
  TimeNs start_t_ = 0;
  TimeNs last_tracked_t_ = 0;
  TimeNs prev_t_ = 0;
  int gaps_ = 0;
  std::optional<TimeNs> low_consensus_since_;  // the first frame of the current low-consensus streak
  TimeNs last_low_consensus_t_ = 0;            // its last judged frame
  struct NisFrame {
    double sum = 0.0;
    int count = 0;
  };
  RingBuffer<NisFrame> nis_;
};

}  // namespace rtslam::slam
