#pragma once
// Rotations and quaternions with analytic Jacobians.
//
// Conventions (../shared/MATH.md, "Rotations"):
// - Hamilton quaternions, right-handed. State vectors store [qw qx qy qz]; Eigen::Quaterniond stores x y z w
//   internally, so convert with quat_from_wxyz / quat_to_wxyz, never by copying memory.
// - q_AB maps vectors of frame B into frame A: v_A = R(q_AB) v_B.
// - Orientation uncertainty is 3-dof with a RIGHT perturbation: q = q̂ ⊗ Exp(δθ), δθ expressed in the local
//   (body) frame. Every Jacobian "with respect to a quaternion" below is with respect to that δθ.
// - Exp(θ) = [cos(|θ|/2), sin(|θ|/2) θ/|θ|]; Log is its inverse with w >= 0 (angles in [0, π]).
// Jacobians are optional output pointers (nullptr: not computed), named J_out_in.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace rtslam::math {

using Eigen::Matrix3d;
using Eigen::Matrix4d;
using Eigen::Quaterniond;
using Eigen::Vector3d;
using Eigen::Vector4d;

/// Below this angle (rad) Exp/Log and the SO(3) Jacobians use their Taylor series.
constexpr double kSmallAngle = 1e-8;

/// [v]x: the skew-symmetric matrix with [v]x w = v × w.
Matrix3d skew(const Vector3d& v);

/// State-vector [qw qx qy qz] <-> Eigen quaternion (explicit, element by element).
Quaterniond quat_from_wxyz(const Eigen::Ref<const Vector4d>& wxyz);
Vector4d quat_to_wxyz(const Quaterniond& q);

/// Exp: rotation vector (rad) -> unit quaternion. J_q_theta is the right Jacobian Jr(θ):
/// Exp(θ + δ) = Exp(θ) ⊗ Exp(Jr(θ) δ) to first order.
Quaterniond exp_so3(const Vector3d& theta, Matrix3d* J_q_theta = nullptr);

/// Log: unit quaternion -> rotation vector with |θ| <= π (w >= 0 branch). J_theta_q is Jr⁻¹(θ):
/// Log(q ⊗ Exp(δ)) = Log(q) + Jr⁻¹(θ) δ to first order. Near |θ| = π the Jacobian is ill-conditioned (valid).
Vector3d log_so3(const Quaterniond& q, Matrix3d* J_theta_q = nullptr);

/// Right Jacobian of SO(3) and its inverse (series below kSmallAngle).
Matrix3d right_jacobian(const Vector3d& theta);
Matrix3d right_jacobian_inverse(const Vector3d& theta);

/// q ⊕ δθ = q ⊗ Exp(δθ) (the retraction of every orientation state block).
Quaterniond boxplus(const Quaterniond& q, const Vector3d& delta);
/// q1 ⊖ q0 = Log(q0⁻¹ ⊗ q1), so that q0 ⊕ (q1 ⊖ q0) = q1.
Vector3d boxminus(const Quaterniond& q1, const Quaterniond& q0);

/// v_A = R(q_AB) v_B. J_vA_q = −R [v_B]x (w.r.t. δθ of q_AB), J_vA_v = R.
Vector3d rotate(const Quaterniond& q_AB, const Vector3d& v_B, Matrix3d* J_vA_q = nullptr,
                Matrix3d* J_vA_v = nullptr);

/// v_B = R(q_AB)ᵀ v_A. J_vB_q = [R ᵀv_A]x (w.r.t. δθ of q_AB), J_vB_v = Rᵀ.
Vector3d rotate_inverse(const Quaterniond& q_AB, const Vector3d& v_A, Matrix3d* J_vB_q = nullptr,
                        Matrix3d* J_vB_v = nullptr);

/// q_AC = q_AB ⊗ q_BC. J_qAC_qAB = R(q_BC)ᵀ, J_qAC_qBC = I (both for right perturbations).
Quaterniond compose(const Quaterniond& q_AB, const Quaterniond& q_BC, Matrix3d* J_qAC_qAB = nullptr,
                    Matrix3d* J_qAC_qBC = nullptr);

/// q_BA = q_AB⁻¹. J_qBA_qAB = −R(q_AB).
Quaterniond inverse(const Quaterniond& q_AB, Matrix3d* J_qBA_qAB = nullptr);

/// Normalizes an ambient 4-vector quaternion; J_out_in is the 4x4 Jacobian (I − q̂q̂ᵀ)/|q|.
Vector4d normalize_quaternion(const Eigen::Ref<const Vector4d>& q, Matrix4d* J_out_in = nullptr);

/// A rigid transform T_AB = (q_AB, p_AB): p_A = R(q_AB) p_B + p_AB.
struct Pose {
  Quaterniond q = Quaterniond::Identity();
  Vector3d p = Vector3d::Zero();

  static Pose identity() { return {}; }
  /// T_AB * p_B.
  Vector3d transform(const Vector3d& p_B) const { return q * p_B + p; }
  /// T_AB⁻¹ * p_A.
  Vector3d inverse_transform(const Vector3d& p_A) const { return q.conjugate() * (p_A - p); }
  Pose inverse() const { return {q.conjugate(), -(q.conjugate() * p)}; }
  /// T_AC = T_AB * T_BC.
  Pose operator*(const Pose& T_BC) const { return {q * T_BC.q, q * T_BC.p + p}; }
  Eigen::Isometry3d isometry() const;
  static Pose from_isometry(const Eigen::Isometry3d& T);
};

/// Jacobians of T_AC = T_AB * T_BC for pose blocks ordered [δp δθ] (p in A, right perturbation of q):
/// J_TAC_TAB (6x6) and J_TAC_TBC (6x6).
Pose compose_poses(const Pose& T_AB, const Pose& T_BC, Eigen::Matrix<double, 6, 6>* J_TAC_TAB = nullptr,
                   Eigen::Matrix<double, 6, 6>* J_TAC_TBC = nullptr);

}  // namespace rtslam::math
