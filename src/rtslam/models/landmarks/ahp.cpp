#include "rtslam/models/landmarks/ahp.hpp"

#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"

namespace rtslam::models {

void AhpPrior::validate(const std::string& where) const {
  // d_min is the distance of the closest features: from a millimetre (a microscope) to 10 km (aerial).
  if (!(d_min >= 1e-3 && d_min <= 1e4)) {
    throw ConfigError(fmt::format("{}: d_min = {} must be in [1e-3, 1e4] m", where, d_min));
  }
  if (!(sigma_ratio > 0.0 && sigma_ratio <= 5.0)) {
    throw ConfigError(fmt::format("{}: depth_prior_sigma_ratio = {} must be in (0, 5]", where, sigma_ratio));
  }
}

Vector7d ahp_from_ray(const math::Pose& T_WS, const Eigen::Vector3d& ray_S, double rho,
                      Eigen::Matrix<double, 7, 3>* J_L_pWS, Eigen::Matrix<double, 7, 3>* J_L_qWS,
                      Eigen::Matrix<double, 7, 3>* J_L_ray, Eigen::Matrix<double, 7, 1>* J_L_rho) {
  const double n = ray_S.norm();
  RTSLAM_CHECK(n > 0.0, "ahp_from_ray: the ray must be non-zero");
  const Eigen::Vector3d u_S = ray_S / n;
  const Eigen::Matrix3d R_WS = T_WS.q.toRotationMatrix();
  Vector7d L;
  L << T_WS.p, R_WS * u_S, rho;
  if (J_L_pWS) {
    J_L_pWS->setZero();
    J_L_pWS->topRows<3>().setIdentity();
  }
  if (J_L_qWS) {
    J_L_qWS->setZero();
    J_L_qWS->middleRows<3>(3) = -R_WS * math::skew(u_S);
  }
  if (J_L_ray) {
    J_L_ray->setZero();
    J_L_ray->middleRows<3>(3) = R_WS * (Eigen::Matrix3d::Identity() - u_S * u_S.transpose()) / n;
  }
  if (J_L_rho) {
    J_L_rho->setZero();
    (*J_L_rho)[6] = 1.0;
  }
  return L;
}

Eigen::Vector3d ahp_to_sensor(const Vector7d& L, const math::Pose& T_WS, Eigen::Matrix3d* J_h_pWS,
                              Eigen::Matrix3d* J_h_qWS, Eigen::Matrix<double, 3, 7>* J_h_L) {
  const Eigen::Vector3d p0 = L.head<3>();
  const Eigen::Vector3d m = L.segment<3>(3);
  const double rho = L[6];
  const Eigen::Matrix3d R_SW = T_WS.q.toRotationMatrix().transpose();
  const Eigen::Vector3d d_W = T_WS.p - p0;
  const Eigen::Vector3d h_S = R_SW * (m - rho * d_W);
  if (J_h_pWS) *J_h_pWS = -rho * R_SW;
  if (J_h_qWS) *J_h_qWS = math::skew(h_S);
  if (J_h_L) {
    J_h_L->leftCols<3>() = rho * R_SW;
    J_h_L->middleCols<3>(3) = R_SW;
    J_h_L->col(6) = -R_SW * d_W;
  }
  return h_S;
}

Eigen::Vector3d ahp_to_euclidean(const Vector7d& L, Eigen::Matrix<double, 3, 7>* J_p_L) {
  const Eigen::Vector3d m = L.segment<3>(3);
  const double inv_rho = 1.0 / L[6];
  if (J_p_L) {
    J_p_L->leftCols<3>().setIdentity();
    J_p_L->middleCols<3>(3) = inv_rho * Eigen::Matrix3d::Identity();
    J_p_L->col(6) = -m * inv_rho * inv_rho;
  }
  return L.head<3>() + m * inv_rho;
}

double ahp_distance(const Vector7d& L, Eigen::Matrix<double, 1, 7>* J_d_L) {
  const Eigen::Vector3d m = L.segment<3>(3);
  const double nm = m.norm();
  const double rho = L[6];
  if (J_d_L) {
    J_d_L->setZero();
    if (nm > 0.0) J_d_L->segment<3>(3) = m.transpose() / (nm * rho);
    (*J_d_L)[6] = -nm / (rho * rho);
  }
  return nm / rho;
}

Vector7d ahp_normalize(const Vector7d& L, Eigen::Matrix<double, 7, 7>* J_out_L) {
  const Eigen::Vector3d m = L.segment<3>(3);
  const double nm = m.norm();
  RTSLAM_CHECK(nm > 0.0, "ahp_normalize: the direction m must be non-zero");
  const double s = 1.0 / nm;
  Vector7d out = L;
  out.segment<3>(3) = s * m;
  out[6] = s * L[6];
  if (J_out_L) {
    // d(m/|m|)/dm = (I − u uᵀ)/|m|; d(ρ/|m|)/dm = −ρ mᵀ/|m|³; d(ρ/|m|)/dρ = 1/|m|.
    const Eigen::Vector3d u = s * m;
    J_out_L->setIdentity();
    J_out_L->block<3, 3>(3, 3) = s * (Eigen::Matrix3d::Identity() - u * u.transpose());
    J_out_L->block<1, 3>(6, 3) = -L[6] * s * s * u.transpose();
    (*J_out_L)(6, 6) = s;
  }
  return out;
}

double ahp_linearity_index(const Vector7d& L, const Eigen::Matrix<double, 7, 7>& P_L, const Eigen::Vector3d& p_WS) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const double rho = L[6];
  const Eigen::Vector3d m = L.segment<3>(3);
  const double nm = m.norm();
  if (!(rho > 0.0) || !(nm > 0.0)) return kInf;
  Eigen::Matrix<double, 1, 7> J_d_L;
  ahp_distance(L, &J_d_L);
  const double var_d = (J_d_L * P_L * J_d_L.transpose())(0, 0);
  const double sigma_d = std::sqrt(std::max(0.0, var_d));
  const Eigen::Vector3d ray_W = L.head<3>() + m / rho - p_WS;
  const double d1 = ray_W.norm();
  if (!(d1 > 0.0)) return kInf;
  const double cos_alpha = m.dot(ray_W) / (nm * d1);
  return 4.0 * sigma_d * std::abs(cos_alpha) / d1;
}

}  // namespace rtslam::models
