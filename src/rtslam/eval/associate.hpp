#pragma once
// Association of an estimate with its ground truth by timestamp, with evo's rule (sync.associate_trajectories):
// for every pose of the SHORTER trajectory (the estimate on a tie), the pose of the longer one with the nearest
// timestamp (the first on a tie) is taken if |Δt| <= max_diff; the estimate's stamps are shifted by offset first.
// Trajectories without timestamps (KITTI) are associated by index and must have the same length.
// With `interpolate`, the ground truth is instead evaluated AT each estimate's timestamp: position linearly,
// attitude by slerp, velocity linearly, between the two ground-truth poses around it when both lie within
// `max_gap_s` of each other (estimates outside the ground truth's span or in a larger gap are dropped). For ground
// truth sampled at other instants than the images (e.g. 200 Hz mocap against 20 Hz images), where nearest-neighbour
// association pairs poses up to half a period apart.
#include <utility>

#include "rtslam/core/time.hpp"
#include "rtslam/core/trajectory.hpp"

namespace rtslam::eval {

struct AssociationOptions {
  double max_diff_s = 0.01;  // evo's default --t_max_diff
  double offset_s = 0.0;     // added to the estimate's timestamps before matching (evo's --t_offset)
  bool interpolate = false;  // ground truth interpolated at the estimate's timestamps (see above)
  double max_gap_s = 0.1;    // interpolate only between ground-truth poses at most this far apart
};

/// Associated copies {est, gt}: same length, pose i of one matches pose i of the other. Throws DataError when either
/// is empty (naming it), when no pose matches (naming both sources) or when index association meets different
/// lengths.
std::pair<Trajectory, Trajectory> associate(const Trajectory& est, const Trajectory& gt,
                                            const AssociationOptions& options = {});

}  // namespace rtslam::eval
