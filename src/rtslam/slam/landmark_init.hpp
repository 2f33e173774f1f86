#pragma once
// Landmark creation and reparametrization shared by every point data/map manager.
#include <Eigen/Core>

#include "rtslam/models/landmarks/ahp.hpp"
#include "rtslam/slam/map.hpp"

namespace rtslam::slam {

/// Undelayed AHP initialization (../shared/MATH.md "Landmarks") from a measured pixel of `sensor`:
/// p0 = p_WS, m = R_WS normalize(back_project(z)), ρ ~ N(ρ̄, σ_ρ²) from the prior. The block's covariance comes
/// from the robot pose (cross-covariances included), the pixel noise sigma_px and the ρ prior.
/// Returns nullptr if the pixel cannot be back-projected or the map has no room.
Landmark* init_ahp_landmark(Map& map, Sensor& sensor, const Eigen::Vector2d& z, double sigma_px,
                            const models::AhpPrior& prior, long frame);

/// AHP → Euclidean: p = p0 + m/ρ with J_p_L applied to the block and its cross-covariances; the 7 rows return to
/// the allocator. Returns the new landmark (nullptr: no room; the AHP landmark stays).
Landmark* reparametrize_to_euclidean(Map& map, Landmark& ahp);

/// The linearity index of an AHP landmark seen from a sensor position p_WS (MATH.md); +inf for other types.
double linearity_index(const Map& map, const Landmark& lmk, const Eigen::Vector3d& p_WS);

}  // namespace rtslam::slam
