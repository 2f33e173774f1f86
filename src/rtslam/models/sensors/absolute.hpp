#pragma once
// Absolute sensors: measurements of the robot pose in the sensor's own world frame, which the estimator takes as
// its world frame W (a GPS-like antenna position, a motion-capture marker body pose).
//
//  - Position (GPS-like): an antenna A at the lever arm p_RA on the robot; z = p_WA = p_WR + R_WR p_RA (m, in W).
//    J_z_TWR (3×6) over the robot pose tangent [δp δθ] (p in W, right perturbation q_WR ⊕ δθ = q_WR ⊗ Exp(δθ)):
//    [I, −R_WR [p_RA]×].
//  - Pose (motion capture): a marker body M at T_RM on the robot; z = T_WM = T_WR T_RM. The innovation is the
//    tangent difference y = z ⊖ h = [p_z − p_h; Log(q_h⁻¹ q_z)] (6, [m; rad]), and J_y_TWR (6×6) is the Jacobian of
//    h(x) in that chart at the current residual: ∂y/∂δ = −J_y_TWR. With the rotation residual r = Log(q_h⁻¹ q_z),
//    h(x ⊕ δ) = q_h Exp(R_RMᵀ δθ) gives r(δ) ≈ r − J_l⁻¹(r) R_RMᵀ δθ, so the rotation rows are J_l⁻¹(r) R_RMᵀ
//    (J_l(r) = J_r(−r)); at r = 0 they are R_RMᵀ. The position rows are [I, −R_WR [p_RM]×].
// Every function is valid everywhere (no domain restriction); the Jacobians are checked numerically in
// tests/models/test_absolute.cpp.
#include <Eigen/Core>

#include "rtslam/math/rotation.hpp"

namespace rtslam::models {

/// p_WA = p_WR + R_WR p_RA, with J_z_TWR = ∂p_WA/∂[δp δθ] (3×6) if requested.
Eigen::Vector3d absolute_position(const math::Pose& T_WR, const Eigen::Vector3d& p_RA,
                                  Eigen::Matrix<double, 3, 6>* J_z_TWR = nullptr);

/// T_WM = T_WR T_RM, with J_TWM_TWR (6×6, [δp δθ] both sides) if requested.
math::Pose absolute_pose(const math::Pose& T_WR, const math::Pose& T_RM,
                         Eigen::Matrix<double, 6, 6>* J_TWM_TWR = nullptr);

/// The pose innovation y = z ⊖ h = [p_z − p_h; Log(q_h⁻¹ q_z)] of a measured pose z against the predicted h, and
/// J_y_h (6×6): ∂y/∂δh for h ⊕ δh (right perturbation), i.e. −[I 0; 0 J_l⁻¹(r)].
Eigen::Matrix<double, 6, 1> pose_innovation(const math::Pose& z, const math::Pose& h,
                                            Eigen::Matrix<double, 6, 6>* J_y_h = nullptr);

}  // namespace rtslam::models
