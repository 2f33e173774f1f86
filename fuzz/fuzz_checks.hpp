#pragma once
// Post-conditions of successful loads, checked by the fuzz targets: what a loader returns must be usable (finite
// values in their documented bounds), or the loader should have thrown. A violation is a finding.
#include <string>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/io/calibration.hpp"

namespace rtslam::fuzz {

/// Width/height > 0 (unless `size_known` is false: KITTI's calib.txt has no size), fx, fy > 0, everything finite,
/// the coefficient count of the model, T_RS a rigid transform.
void check_camera(const io::CameraCalibration& cam, bool size_known = true);
/// Rates and noise densities > 0, random walks and saturations >= 0 / > 0, finite; T_RS a rigid transform.
void check_imu(const io::ImuCalibration& imu);
void check_rig(const io::Rig& rig);

/// Finite positions, unit quaternions (within the readers' 1e-2), strictly increasing times when timestamped,
/// finite optional groups and a symmetric covariance.
void check_trajectory(const Trajectory& traj);

/// Two rigs are the same to the last bit (a write/read round trip).
void check_same_rig(const io::Rig& a, const io::Rig& b);

}  // namespace rtslam::fuzz
