#pragma once
// The per-frame record the viewer keeps for every processed image, dropped or not (the trajectory and the plots of
// a live run, the whole of a replayed one), and the pose NEES against a ground truth.
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/viz/report.hpp"

namespace rtslam::viz {

struct HistoryEntry {
  int index = 0;
  TimeNs t = 0;
  math::Pose T_WR;
  std::optional<Eigen::Matrix<double, 6, 6>> cov;  // [δp δθ] pose covariance (filter convention)
  slam::FrameStats stats;                          // counts (and timings when has_timing)
  bool has_stats = false;
  bool has_timing = false;
  Nis nis;                                         // count 0: none
  double nees = std::numeric_limits<double>::quiet_NaN();  // NaN: no ground truth or no usable covariance
};

/// The record of one report (NEES left NaN: see NeesTracker).
HistoryEntry summarize(const FrameReport& report);

/// Pose NEES of successive estimates against a ground truth, as eval::compute_nees defines it (eval/nees.hpp): the
/// ground truth is brought into the filter's world frame by the first-pose alignment of the first estimate that
/// has a ground-truth pose within `max_dt_s`, e = [p_gt' − p ; Log(q⁻¹ ⊗ q_gt')], ε = eᵀ P⁻¹ e.
class NeesTracker {
 public:
  explicit NeesTracker(Trajectory ground_truth, double max_dt_s = 0.02);
  /// NaN when the entry has no covariance, the covariance is not positive definite, or no ground-truth pose is
  /// near its time.
  double nees(const HistoryEntry& e);
  /// The ground-truth pose nearest to t within max_dt_s.
  const StampedPose* nearest(TimeNs t) const;

 private:
  Trajectory gt_;
  TimeNs max_dt_ns_;
  bool gauge_set_ = false;
  math::Pose S_;  // gt' = S ∘ gt
};

}  // namespace rtslam::viz
