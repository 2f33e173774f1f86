#include "rtslam/models/landmarks/euclidean_point.hpp"

#include "rtslam/core/error.hpp"

namespace rtslam::models {

Eigen::Vector3d point_to_sensor(const Eigen::Vector3d& p_W, const math::Pose& T_WS, Eigen::Matrix3d* J_h_pWS,
                                Eigen::Matrix3d* J_h_qWS, Eigen::Matrix3d* J_h_p) {
  const Eigen::Matrix3d R_SW = T_WS.q.toRotationMatrix().transpose();
  const Eigen::Vector3d h_S = R_SW * (p_W - T_WS.p);
  if (J_h_pWS) *J_h_pWS = -R_SW;
  if (J_h_qWS) *J_h_qWS = math::skew(h_S);
  if (J_h_p) *J_h_p = R_SW;
  return h_S;
}

Eigen::Vector3d point_from_ray(const math::Pose& T_WS, const Eigen::Vector3d& ray_S, double distance,
                               Eigen::Matrix3d* J_p_pWS, Eigen::Matrix3d* J_p_qWS, Eigen::Matrix3d* J_p_ray,
                               Eigen::Vector3d* J_p_d) {
  const double n = ray_S.norm();
  RTSLAM_CHECK(n > 0.0, "point_from_ray: the ray must be non-zero");
  const Eigen::Vector3d u_S = ray_S / n;
  const Eigen::Matrix3d R_WS = T_WS.q.toRotationMatrix();
  const Eigen::Vector3d u_W = R_WS * u_S;
  if (J_p_pWS) J_p_pWS->setIdentity();
  if (J_p_qWS) *J_p_qWS = -distance * R_WS * math::skew(u_S);
  if (J_p_ray) *J_p_ray = distance * R_WS * (Eigen::Matrix3d::Identity() - u_S * u_S.transpose()) / n;
  if (J_p_d) *J_p_d = u_W;
  return T_WS.p + distance * u_W;
}

}  // namespace rtslam::models
