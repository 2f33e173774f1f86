#pragma once
// Small rigid/similarity-transform helpers for evaluation (kept local to eval/: metrics only need these few).
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace rtslam::eval {

/// A similarity transform x ↦ s R x + t acting on points; on a pose T_WR it maps position and rotation as
/// p' = s R p + t, R' = R R_WR (orientation is unaffected by the scale).
struct Sim3 {
  double s = 1.0;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();

  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return s * (R * p) + t; }
  Sim3 inverse() const {
    Sim3 inv;
    inv.s = 1.0 / s;
    inv.R = R.transpose();
    inv.t = -(inv.s * (inv.R * t));
    return inv;
  }
  /// (this ∘ other)(x) = this(other(x)).
  Sim3 operator*(const Sim3& o) const {
    Sim3 out;
    out.s = s * o.s;
    out.R = R * o.R;
    out.t = s * (R * o.t) + t;
    return out;
  }
};

/// Rotation angle of R in [0, π] (radians), robust near 0 and π (from the quaternion, not acos of the trace).
inline double rotation_angle(const Eigen::Matrix3d& R) {
  const Eigen::Quaterniond q(R);
  return 2.0 * std::atan2(q.vec().norm(), std::abs(q.w()));
}

/// Log map of a unit quaternion: the rotation vector θ with q = Exp(θ), taking the w >= 0 representative.
inline Eigen::Vector3d so3_log(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  if (q.w() < 0.0) q.coeffs() *= -1.0;
  const double n = q.vec().norm();
  if (n < 1e-12) return 2.0 * q.vec() / q.w();  // first-order series, w ≈ 1
  return (2.0 * std::atan2(n, q.w()) / n) * q.vec();
}

/// Rotation about +z by `yaw` radians.
inline Eigen::Matrix3d rot_z(double yaw) {
  return Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

}  // namespace rtslam::eval
