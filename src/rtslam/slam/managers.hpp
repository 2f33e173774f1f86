#pragma once
// The strategy interfaces of the paper: a DataManager per sensor (and landmark type) turns raw data into
// corrections and new landmarks; a MapManager per map keeps it clean and bounded (reparametrization, removal).
// Implementations live in strategies/; the System only sees these interfaces.
#include <string>

#include <Eigen/Core>

#include "rtslam/core/time.hpp"
#include "rtslam/slam/fwd.hpp"

namespace rtslam::slam {

/// Raw data of one sensor at one time (an image, a list of simulated point measurements, ...).
struct RawData {
  virtual ~RawData() = default;
  /// Drops what the datum holds (pixels) once the System is done with it; the object itself is reused.
  virtual void release() {}
  TimeNs t = 0;
  int sensor_id = 0;
};

/// Per-frame statistics the data manager fills (written to frames.csv later).
struct FrameStats {
  TimeNs t = 0;
  // The map's frame of this datum: one robot's landmark-sensor data of one time share it (a stereo pair is one frame;
  // several robots' images count one each), and the map manager's frame-counted settings and the landmarks' counters
  // count these frames. `sensor_id`: the datum's sensor.
  long frame = 0;
  int sensor_id = -1;
  int landmarks_in_map = 0;
  int visible = 0;
  int searched = 0;
  int matched = 0;
  int updated = 0;
  int initialized = 0;
  int ransac_inliers = 0;
  int ransac_hypotheses = 0;  // one-point RANSAC hypotheses evaluated (matched in their full ellipse)
  int ransac_max = 0;         // when one-point RANSAC tested a hypothesis: the most inliers it applies (its cap)
  int fallback = 0;  // of `visible`: admitted although their box exceeded max_search_size_px2 (search/min_candidates)
  int reparametrized = 0;
  int removed = 0;
  int evicted = 0;  // of `removed`: dropped to make room in a full map
  int refused = 0;  // corrections the filter refused (S not positive definite, a variance would turn negative)
  // The datum's sensor observes landmarks (a camera). False for absolute sensors (slam/absolute_sensor.hpp): the
  // health monitor then judges only the state, not the tracking (no landmark is expected to be matched).
  bool landmark_frame = true;
  int absolute_updates = 0;   // absolute position/pose corrections applied (strategies/absolute.hpp)
  int absolute_rejected = 0;  // absolute corrections gated out or refused by the filter
  bool zero_velocity = false;  // a zero-velocity update was applied after the frame (strategies/zero_velocity.hpp)
  // Normalized innovation squared (z − h₀)ᵀ S₀⁻¹ (z − h₀) of the matched observations at their first prediction of
  // the frame, summed, and their number (2 dof each): the health monitor's consistency signal.
  double nis = 0.0;
  int nis_count = 0;
  int health = 0;   // slam::Health of the frame (0 ok, 1 lost, 2 diverged) as judged after it
  bool reset = false;  // the robot and the map were re-initialized after this frame
  // The search's time budget (strategies/active_search.hpp, search/time_budget_ms): whether it ran out in this frame,
  // the visible landmarks left unsearched because of it, and the search's time (RANSAC + active search + their
  // corrections, measured by the budget's clock when a budget is set).
  bool budget_hit = false;
  int budget_skipped = 0;
  double time_search_ms = 0.0;
  // Wall times of the frame's stages; predict + match + ransac + update + init + map ≈ total.
  double time_predict_ms = 0.0;  // robots to the datum's time, observation predictions
  double time_match_ms = 0.0;    // appearance matching (ZNCC searches), in every stage
  double time_ransac_ms = 0.0;   // one-point RANSAC: hypotheses, their support and the batched update, not matching
  double time_update_ms = 0.0;   // the other updates (gated active search), not matching
  double time_init_ms = 0.0;
  double time_map_ms = 0.0;
  double time_total_ms = 0.0;
};

class MapManager {
 public:
  virtual ~MapManager() = default;
  /// Whether a landmark block of `tangent_size` rows may be added now.
  virtual bool has_room(const Map& map, int tangent_size) const = 0;
  /// After every frame of `sensor`: reparametrize and remove landmarks according to the policy.
  virtual void manage(Map& map, const Sensor& sensor, long frame, FrameStats& stats) = 0;
};

class DataManager {
 public:
  virtual ~DataManager() = default;
  /// Processes one raw datum of its sensor: observe, correct, initialize. The robot is already at raw.t.
  virtual void process(Map& map, Sensor& sensor, const RawData& raw, long frame, FrameStats& stats) = 0;
  virtual std::string name() const = 0;
  /// The map's unit of length changed by c about `centre` (Map::scale_lengths): what the manager keeps in W for the
  /// landmarks its sensor made (the views of their patches) follows. Nothing by default.
  virtual void scale_lengths(Map& /*map*/, const Sensor& /*sensor*/, double /*c*/, const Eigen::Vector3d& /*centre*/) {}
};

}  // namespace rtslam::slam
