#include "rtslam/models/sensors/absolute.hpp"

namespace rtslam::models {

Eigen::Vector3d absolute_position(const math::Pose& T_WR, const Eigen::Vector3d& p_RA,
                                  Eigen::Matrix<double, 3, 6>* J_z_TWR) {
  const Eigen::Matrix3d R_WR = T_WR.q.toRotationMatrix();
  if (J_z_TWR != nullptr) {
    J_z_TWR->leftCols<3>().setIdentity();
    J_z_TWR->rightCols<3>() = -R_WR * math::skew(p_RA);
  }
  return T_WR.p + R_WR * p_RA;
}

math::Pose absolute_pose(const math::Pose& T_WR, const math::Pose& T_RM, Eigen::Matrix<double, 6, 6>* J_TWM_TWR) {
  return math::compose_poses(T_WR, T_RM, J_TWM_TWR, nullptr);
}

Eigen::Matrix<double, 6, 1> pose_innovation(const math::Pose& z, const math::Pose& h,
                                            Eigen::Matrix<double, 6, 6>* J_y_h) {
  Eigen::Matrix<double, 6, 1> y;
  y.head<3>() = z.p - h.p;
  y.tail<3>() = math::log_so3(h.q.conjugate() * z.q);
  if (J_y_h != nullptr) {
    // r(δ) = Log(Exp(−δ) q_h⁻¹ q_z) ≈ r − J_l⁻¹(r) δ, J_l(r) = J_r(−r).
    J_y_h->setZero();
    J_y_h->topLeftCorner<3, 3>() = -Eigen::Matrix3d::Identity();
    J_y_h->bottomRightCorner<3, 3>() = -math::right_jacobian_inverse(-y.tail<3>());
  }
  return y;
}

}  // namespace rtslam::models
