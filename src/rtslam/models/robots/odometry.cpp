#include "rtslam/models/robots/odometry.hpp"

#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::models {

void OdometryParams::validate() const {
  // Upper bound: 10 m/√s (or m/√m) of odometry noise is no odometry any more, only a numerical hazard.
  const auto check = [](double v, const char* key, const char* unit) {
    if (!(v >= 0.0 && v <= 10.0)) throw ConfigError(fmt::format("odometry/{} = {} must be in [0, 10] {}", key, v, unit));
  };
  check(sigma_p, "sigma_p", "m/sqrt(s)");
  check(sigma_theta, "sigma_theta", "rad/sqrt(s)");
  check(k_p, "k_p", "m/sqrt(m)");
  check(k_theta, "k_theta", "rad/sqrt(rad)");
}

Matrix6d odometry_input_covariance(const OdometryIncrement& u, const OdometryParams& params) {
  Matrix6d U = Matrix6d::Zero();
  const double dt = std::max(u.dt, 0.0);
  U.diagonal().head<3>().setConstant(params.sigma_p * params.sigma_p * dt + params.k_p * params.k_p * u.dp.norm());
  U.diagonal().tail<3>().setConstant(params.sigma_theta * params.sigma_theta * dt +
                                     params.k_theta * params.k_theta * u.dtheta.norm());
  return U;
}

void odometry_predict(const Vector7d& x, const OdometryIncrement& u, Vector7d& x_out, Matrix6d* F, Matrix6d* G) {
  using I = OdometryIndex;
  const Eigen::Vector3d p = x.segment<3>(I::kP);
  const Eigen::Quaterniond q = math::quat_from_wxyz(x.segment<4>(I::kQ));
  const Eigen::Matrix3d R = q.toRotationMatrix();
  Eigen::Matrix3d Jr;
  const Eigen::Quaterniond dq = math::exp_so3(u.dtheta, G ? &Jr : nullptr);
  if (F) {
    F->setIdentity();
    F->block<3, 3>(I::kDp, I::kDth) = -R * math::skew(u.dp);
    F->block<3, 3>(I::kDth, I::kDth) = dq.toRotationMatrix().transpose();
  }
  if (G) {
    G->setZero();
    G->block<3, 3>(I::kDp, 0) = R;
    G->block<3, 3>(I::kDth, 3) = Jr;
  }
  // Every input is read above, so x_out may alias x.
  x_out.segment<3>(I::kP) = p + R * u.dp;
  x_out.segment<4>(I::kQ) = math::quat_to_wxyz((q * dq).normalized());
}

}  // namespace rtslam::models
