#pragma once
// A change of the map's world frame: every robot and landmark re-expressed in a new frame G, with the uncertainty
// of the change added. Absolute sensors use it once, to bring the frame the robot started in (the gauge of the
// first pose) into the sensor's frame when the first fixes have told where that frame lies
// (strategies/absolute.hpp).
//
// The change is x_G = R_GW x_W + t_GW for points. Per block (tangent rows, right perturbation of attitudes):
//   robot [p q v ...]  p' = R p + t, q' = q_GW q, v' = R v (constant velocity: ω in R unchanged; inertial: the
//                      biases in R unchanged, gravity g' = R g)        J = diag(R, I, R, ...)
//                      (odometry robot [p q]: p' = R p + t, q' = q_GW q  J = diag(R, I))
//   AHP [p0 m ρ]       p0' = R p0 + t, m' = R m, ρ' = ρ                  J = diag(R, R, 1)
//   Euclidean [x]      x' = R x + t                                      J = R
//   any other block    (sensor extrinsics T_RS, in R) unchanged          J = I
// and the covariance P ← J P Jᵀ + Γ Σ Γᵀ, where Σ (6×6) is the covariance of the change itself as [δc δφ]: a
// translation δc and a rotation δφ (in G) about the point c_G, so that a point moves by δx = δc − [x − c_G]× δφ, an
// attitude by δθ = R_GRᵀ δφ, a vector v by −[v]× δφ (Γ: those rows at the new mean; the same directions as
// Robot::nullspace). Every block's uncertainty relative to the others is kept; the world frame's own uncertainty
// enters as a common motion of everything.
#include <functional>
#include <string>

#include <Eigen/Core>

#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/fwd.hpp"

namespace rtslam::slam {

struct WorldChange {
  math::Pose T_GW;                                    // x_G = T_GW x_W
  Eigen::Vector3d center_G = Eigen::Vector3d::Zero();  // c_G, the point the rotation uncertainty turns about
  Eigen::Matrix<double, 6, 6> cov = Eigen::Matrix<double, 6, 6>::Zero();  // of [δc δφ] (m², rad²)
};

/// Re-expresses the map in G (header comment). `on_landmark` is called for every landmark after its block moved
/// (its descriptor may hold poses in W, e.g. the view a patch was taken from). With slam/consistency: oc the tracked basis of the
/// world frame's directions is recomputed at the new means (camera measurements still cannot observe the world
/// frame; only the absolute sensor does). Returns an empty string, or why the change is not possible (a robot type
/// it does not know) — the map is then untouched. Allocates: a one-time operation, not for the per-frame path.
std::string change_world_frame(Map& map, const WorldChange& change,
                               const std::function<void(Landmark&, const math::Pose& T_GW)>& on_landmark = {});

}  // namespace rtslam::slam
