#pragma once
// Euclidean point landmark L = [x y z] in the world frame W (../shared/MATH.md, "Landmarks").
//
// Jacobians with respect to an orientation are with respect to its right perturbation q ⊕ δθ = q ⊗ Exp(δθ)
// (math/rotation.hpp); positions are Euclidean. Optional output pointers, nullptr = not computed.
#include <Eigen/Core>

#include "rtslam/math/rotation.hpp"

namespace rtslam::models {

/// The point in the sensor frame S: h_S = R_WSᵀ (p_W − p_WS). Jacobians J_h_pWS = −R_WSᵀ,
/// J_h_qWS = [h_S]x, J_h_p = R_WSᵀ (3x3 each).
Eigen::Vector3d point_to_sensor(const Eigen::Vector3d& p_W, const math::Pose& T_WS, Eigen::Matrix3d* J_h_pWS = nullptr,
                                Eigen::Matrix3d* J_h_qWS = nullptr, Eigen::Matrix3d* J_h_p = nullptr);

/// Initialization of a Euclidean point at a known distance along a ray: p_W = p_WS + d · R_WS normalize(ray_S).
/// (For stereo or known-landmark initialization.) J_p_pWS = I, J_p_qWS, J_p_ray, J_p_d (3x1).
Eigen::Vector3d point_from_ray(const math::Pose& T_WS, const Eigen::Vector3d& ray_S, double distance,
                               Eigen::Matrix3d* J_p_pWS = nullptr, Eigen::Matrix3d* J_p_qWS = nullptr,
                               Eigen::Matrix3d* J_p_ray = nullptr, Eigen::Vector3d* J_p_d = nullptr);

}  // namespace rtslam::models
