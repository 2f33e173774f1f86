#include "rtslam/math/rotation.hpp"

#include <cmath>

namespace rtslam::math {

Matrix3d skew(const Vector3d& v) {
  Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

Quaterniond quat_from_wxyz(const Eigen::Ref<const Vector4d>& wxyz) {
  return Quaterniond(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
}

Vector4d quat_to_wxyz(const Quaterniond& q) { return Vector4d(q.w(), q.x(), q.y(), q.z()); }

Matrix3d right_jacobian(const Vector3d& theta) {
  const double a = theta.norm();
  const Matrix3d K = skew(theta);
  if (a < kSmallAngle) return Matrix3d::Identity() - 0.5 * K + K * K / 6.0;
  const double a2 = a * a;
  return Matrix3d::Identity() - (1.0 - std::cos(a)) / a2 * K + (a - std::sin(a)) / (a2 * a) * K * K;
}

Matrix3d right_jacobian_inverse(const Vector3d& theta) {
  const double a = theta.norm();
  const Matrix3d K = skew(theta);
  if (a < kSmallAngle) return Matrix3d::Identity() + 0.5 * K + K * K / 12.0;
  const double a2 = a * a;
  const double c = 1.0 / a2 - (1.0 + std::cos(a)) / (2.0 * a * std::sin(a));
  return Matrix3d::Identity() + 0.5 * K + c * K * K;
}

Quaterniond exp_so3(const Vector3d& theta, Matrix3d* J_q_theta) {
  const double a = theta.norm();
  Quaterniond q;
  if (a < kSmallAngle) {
    // cos(a/2) ≈ 1 − a²/8, sin(a/2)/a ≈ 1/2 − a²/48.
    const double s = 0.5 - a * a / 48.0;
    q = Quaterniond(1.0 - a * a / 8.0, s * theta.x(), s * theta.y(), s * theta.z());
  } else {
    const double s = std::sin(0.5 * a) / a;
    q = Quaterniond(std::cos(0.5 * a), s * theta.x(), s * theta.y(), s * theta.z());
  }
  q.normalize();
  if (J_q_theta) *J_q_theta = right_jacobian(theta);
  return q;
}

Vector3d log_so3(const Quaterniond& q_in, Matrix3d* J_theta_q) {
  Quaterniond q = q_in.normalized();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();  // same rotation, w >= 0 branch
  const Vector3d v = q.vec();
  const double n = v.norm();
  Vector3d theta;
  if (n < kSmallAngle) {
    // θ = 2 atan2(n, w) v/n ≈ (2/w)(1 − n²/(3w²)) v.
    theta = (2.0 / q.w()) * (1.0 - n * n / (3.0 * q.w() * q.w())) * v;
  } else {
    theta = (2.0 * std::atan2(n, q.w()) / n) * v;
  }
  if (J_theta_q) *J_theta_q = right_jacobian_inverse(theta);
  return theta;
}

Quaterniond boxplus(const Quaterniond& q, const Vector3d& delta) { return (q * exp_so3(delta)).normalized(); }

Vector3d boxminus(const Quaterniond& q1, const Quaterniond& q0) { return log_so3(q0.conjugate() * q1); }

Vector3d rotate(const Quaterniond& q_AB, const Vector3d& v_B, Matrix3d* J_vA_q, Matrix3d* J_vA_v) {
  const Matrix3d R = q_AB.toRotationMatrix();
  if (J_vA_q) *J_vA_q = -R * skew(v_B);
  if (J_vA_v) *J_vA_v = R;
  return R * v_B;
}

Vector3d rotate_inverse(const Quaterniond& q_AB, const Vector3d& v_A, Matrix3d* J_vB_q, Matrix3d* J_vB_v) {
  const Matrix3d Rt = q_AB.toRotationMatrix().transpose();
  const Vector3d v_B = Rt * v_A;
  if (J_vB_q) *J_vB_q = skew(v_B);
  if (J_vB_v) *J_vB_v = Rt;
  return v_B;
}

Quaterniond compose(const Quaterniond& q_AB, const Quaterniond& q_BC, Matrix3d* J_qAC_qAB, Matrix3d* J_qAC_qBC) {
  if (J_qAC_qAB) *J_qAC_qAB = q_BC.toRotationMatrix().transpose();
  if (J_qAC_qBC) J_qAC_qBC->setIdentity();
  return q_AB * q_BC;
}

Quaterniond inverse(const Quaterniond& q_AB, Matrix3d* J_qBA_qAB) {
  if (J_qBA_qAB) *J_qBA_qAB = -q_AB.toRotationMatrix();
  return q_AB.conjugate();
}

Vector4d normalize_quaternion(const Eigen::Ref<const Vector4d>& q, Matrix4d* J_out_in) {
  const double n = q.norm();
  const Vector4d u = q / n;
  if (J_out_in) *J_out_in = (Matrix4d::Identity() - u * u.transpose()) / n;
  return u;
}

Eigen::Isometry3d Pose::isometry() const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.toRotationMatrix();
  T.translation() = p;
  return T;
}

Pose Pose::from_isometry(const Eigen::Isometry3d& T) {
  return {Quaterniond(T.linear()).normalized(), T.translation()};
}

Pose compose_poses(const Pose& T_AB, const Pose& T_BC, Eigen::Matrix<double, 6, 6>* J_TAC_TAB,
                   Eigen::Matrix<double, 6, 6>* J_TAC_TBC) {
  // p_AC = R_AB p_BC + p_AB ; q_AC = q_AB ⊗ q_BC.
  Matrix3d J_p_qAB;
  Matrix3d J_p_pBC;
  const Vector3d p_AC = rotate(T_AB.q, T_BC.p, &J_p_qAB, &J_p_pBC) + T_AB.p;
  Matrix3d J_q_qAB;
  const Quaterniond q_AC = compose(T_AB.q, T_BC.q, &J_q_qAB);
  if (J_TAC_TAB) {
    J_TAC_TAB->setZero();
    J_TAC_TAB->block<3, 3>(0, 0).setIdentity();
    J_TAC_TAB->block<3, 3>(0, 3) = J_p_qAB;
    J_TAC_TAB->block<3, 3>(3, 3) = J_q_qAB;
  }
  if (J_TAC_TBC) {
    J_TAC_TBC->setZero();
    J_TAC_TBC->block<3, 3>(0, 0) = J_p_pBC;
    J_TAC_TBC->block<3, 3>(3, 3).setIdentity();
  }
  return {q_AC, p_AC};
}

}  // namespace rtslam::math
