#include "rtslam/models/robots/constant_velocity.hpp"

#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::models {

void ConstantVelocityParams::validate() const {
  // Upper bounds: a velocity random walk of 1000 m/s/√s is no motion model any more, only a numerical hazard.
  if (!(sigma_v >= 0.0 && sigma_v <= 1e3)) {
    throw ConfigError(fmt::format("motion: sigma_v = {} must be in [0, 1e3] m/s/sqrt(s)", sigma_v));
  }
  if (!(sigma_w >= 0.0 && sigma_w <= 1e3)) {
    throw ConfigError(fmt::format("motion: sigma_w = {} must be in [0, 1e3] rad/s/sqrt(s)", sigma_w));
  }
}

void constant_velocity_predict(const Vector13d& x, double dt, const ConstantVelocityParams& params, Vector13d& x_out,
                               Matrix12d* F, Matrix12d* Q) {
  using Idx = ConstantVelocityIndex;
  RTSLAM_CHECK(dt >= 0.0, "constant_velocity_predict: dt must be >= 0");
  const Eigen::Vector3d p = x.segment<3>(Idx::kP);
  const Eigen::Quaterniond q = math::quat_from_wxyz(x.segment<4>(Idx::kQ));
  const Eigen::Vector3d v = x.segment<3>(Idx::kV);
  const Eigen::Vector3d w = x.segment<3>(Idx::kW);

  const Eigen::Vector3d theta = w * dt;
  Eigen::Matrix3d Jr;
  const Eigen::Quaterniond dq = math::exp_so3(theta, F ? &Jr : nullptr);
  const Eigen::Quaterniond q_new = (q * dq).normalized();

  if (F) {
    F->setIdentity();
    F->block<3, 3>(Idx::kDp, Idx::kDv) = dt * Eigen::Matrix3d::Identity();
    F->block<3, 3>(Idx::kDth, Idx::kDth) = dq.toRotationMatrix().transpose();
    F->block<3, 3>(Idx::kDth, Idx::kDw) = dt * Jr;
  }
  if (Q) {
    Q->setZero();
    Q->block<3, 3>(Idx::kDv, Idx::kDv).diagonal().setConstant(params.sigma_v * params.sigma_v * dt);
    Q->block<3, 3>(Idx::kDw, Idx::kDw).diagonal().setConstant(params.sigma_w * params.sigma_w * dt);
  }
  // Every input is read above, so x_out may alias x.
  x_out.segment<3>(Idx::kP) = p + v * dt;
  x_out.segment<4>(Idx::kQ) = math::quat_to_wxyz(q_new);
  x_out.segment<3>(Idx::kV) = v;
  x_out.segment<3>(Idx::kW) = w;
}

}  // namespace rtslam::models
