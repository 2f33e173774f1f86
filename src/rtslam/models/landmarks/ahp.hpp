#pragma once
// Anchored homogeneous point (AHP) landmark L = [p0(3) m(3) ρ(1)] (../shared/MATH.md, "Landmarks"): anchor p0 in W
// (the sensor centre at initialization), direction m in W, inverse distance ρ; the point is p = p0 + m/ρ.
// (m, ρ) has a gauge freedom: (λm, λρ) is the same point for any λ > 0.
//
// Jacobians with respect to an orientation are with respect to its right perturbation q ⊕ δθ = q ⊗ Exp(δθ)
// (math/rotation.hpp). Optional output pointers, nullptr = not computed, named J_out_in.
#include <Eigen/Core>

#include "rtslam/math/rotation.hpp"

namespace rtslam::models {

using Vector7d = Eigen::Matrix<double, 7, 1>;

/// Inverse-distance prior for undelayed initialization: ρ ~ N(1/(2 d_min), (1/(4 d_min))²), so that ±2σ spans
/// depths [d_min, ∞) (RT-SLAM D_MIN = 0.5 m).
struct AhpPrior {
  double d_min = 0.5;         // m
  double sigma_ratio = 0.5;   // σ_ρ / ρ̄ (RT-SLAM: 0.5, ±2σ spanning [d_min, ∞))
  double rho_mean() const { return 1.0 / (2.0 * d_min); }
  double rho_sigma() const { return sigma_ratio * rho_mean(); }
  /// Throws ConfigError naming `where` unless d_min is in [1e-3, 1e4] m and sigma_ratio in (0, 5].
  void validate(const std::string& where = "AHP prior") const;
};

/// Builds L from the sensor pose T_WS and a ray in S (any non-zero scale, e.g. z = 1 from unproject):
/// p0 = p_WS, m = R_WS * normalize(ray_S), rho given. Jacobians: J_L_pWS 7x3, J_L_qWS 7x3 (right perturbation of
/// q_WS), J_L_ray 7x3, J_L_rho 7x1.
Vector7d ahp_from_ray(const math::Pose& T_WS, const Eigen::Vector3d& ray_S, double rho,
                      Eigen::Matrix<double, 7, 3>* J_L_pWS = nullptr, Eigen::Matrix<double, 7, 3>* J_L_qWS = nullptr,
                      Eigen::Matrix<double, 7, 3>* J_L_ray = nullptr, Eigen::Matrix<double, 7, 1>* J_L_rho = nullptr);

/// Homogeneous point in S: h_S = R_WSᵀ (m − ρ (p_WS − p0)), a vector along the sensor-to-point ray (scaled by ρ).
/// Only its direction matters for a camera; it is in front iff h_S.z > 0 (for ρ >= 0).
/// Jacobians J_h_pWS 3x3, J_h_qWS 3x3, J_h_L 3x7.
Eigen::Vector3d ahp_to_sensor(const Vector7d& L, const math::Pose& T_WS, Eigen::Matrix3d* J_h_pWS = nullptr,
                              Eigen::Matrix3d* J_h_qWS = nullptr, Eigen::Matrix<double, 3, 7>* J_h_L = nullptr);

/// p = p0 + m / ρ, J_p_L = [I, I/ρ, −m/ρ²]. Needs ρ ≠ 0 (ρ = 0 is a point at infinity: the result is not finite).
Eigen::Vector3d ahp_to_euclidean(const Vector7d& L, Eigen::Matrix<double, 3, 7>* J_p_L = nullptr);

/// Distance from the anchor d = |m| / ρ and J_d_L (1x7) = [0, mᵀ/(|m| ρ), −|m|/ρ²].
double ahp_distance(const Vector7d& L, Eigen::Matrix<double, 1, 7>* J_d_L = nullptr);

/// Gauge normalization (m, ρ) -> (m, ρ)/|m| so that |m| = 1 (the same point); J_out_L is 7x7. Apply J to the
/// block's covariance and cross-covariances after an update if the filter keeps |m| = 1.
Vector7d ahp_normalize(const Vector7d& L, Eigen::Matrix<double, 7, 7>* J_out_L = nullptr);

/// Linearity index of the inverse-distance coordinate (Civera, Davison, Montiel 2008):
/// L_d = 4 σ_d |cos α| / d1 with d = |m|/ρ, σ_d² = J_d P_L J_dᵀ (P_L the landmark's 7x7 covariance block),
/// d1 = |p − p_WS| the current sensor–point distance, α the angle between m and p − p_WS. Small L_d: the
/// Euclidean parametrization is linear enough (RT-SLAM converts below 0.1). Returns +infinity when ρ <= 0 or the
/// sensor is at the point (never convert).
double ahp_linearity_index(const Vector7d& L, const Eigen::Matrix<double, 7, 7>& P_L, const Eigen::Vector3d& p_WS);

}  // namespace rtslam::models
