#include "rtslam/models/robots/inertial.hpp"

#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::models {

namespace {

void require_density(double value, const char* key, const char* unit) {
  if (!(std::isfinite(value) && value >= 0.0)) {
    throw ConfigError(fmt::format("inertial: {} = {} must be finite and >= 0 ({})", key, value, unit));
  }
}

}  // namespace

void InertialParams::validate() const {
  require_density(accelerometer_noise_density, "accelerometer_noise_density", "m/s^2/sqrt(Hz)");
  require_density(gyroscope_noise_density, "gyroscope_noise_density", "rad/s/sqrt(Hz)");
  require_density(accelerometer_random_walk, "accelerometer_random_walk", "m/s^3/sqrt(Hz)");
  require_density(gyroscope_random_walk, "gyroscope_random_walk", "rad/s^2/sqrt(Hz)");
}

void inertial_step(const Vector19d& x, const ImuMeasurement& imu_k, const ImuMeasurement& imu_k1, double dt,
                   const Vector12d& noise, Vector19d& x_out, Matrix18d* F, Matrix18x12d* G) {
  using Idx = InertialIndex;
  using Eigen::Matrix3d;
  using Eigen::Vector3d;
  RTSLAM_CHECK(dt >= 0.0, "inertial_step: dt must be >= 0");
  const Vector3d p = x.segment<3>(Idx::kP);
  const Eigen::Quaterniond q = math::quat_from_wxyz(x.segment<4>(Idx::kQ));
  const Vector3d v = x.segment<3>(Idx::kV);
  const Vector3d a_b = x.segment<3>(Idx::kAb);
  const Vector3d w_b = x.segment<3>(Idx::kWb);
  const Vector3d g = x.segment<3>(Idx::kG);

  // Attitude: q⁺ = q ⊗ Exp(θ), θ = ω̄ dt + n_θ.
  const Vector3d w_bar = 0.5 * (imu_k.gyro + imu_k1.gyro) - w_b;
  const Vector3d theta = w_bar * dt + noise.segment<3>(Idx::kNth);
  const bool jac = F != nullptr || G != nullptr;
  Matrix3d Jr;
  const Eigen::Quaterniond dq = math::exp_so3(theta, jac ? &Jr : nullptr);
  const Eigen::Quaterniond q_new = (q * dq).normalized();

  // Acceleration: trapezoid of the two rotated specific forces, plus gravity.
  const Matrix3d R = q.toRotationMatrix();
  const Matrix3d R_new = q_new.toRotationMatrix();
  const Vector3d A_k = imu_k.accel - a_b;
  const Vector3d A_k1 = imu_k1.accel - a_b;
  const Vector3d a_bar = 0.5 * (R * A_k + R_new * A_k1) + g;

  const double dt2 = 0.5 * dt * dt;
  if (jac) {
    const Matrix3d I = Matrix3d::Identity();
    const Matrix3d dR_T = dq.toRotationMatrix().transpose();
    const Matrix3d R_new_A1x = R_new * math::skew(A_k1);
    // ∂θ⁺/∂δθ = dRᵀ, ∂θ⁺/∂ω_b = −Jr dt, ∂θ⁺/∂n_θ = Jr.
    const Matrix3d J_abar_th = -0.5 * (R * math::skew(A_k) + R_new_A1x * dR_T);
    const Matrix3d J_abar_ab = -0.5 * (R + R_new);
    const Matrix3d J_abar_wb = 0.5 * dt * R_new_A1x * Jr;
    const Matrix3d J_abar_nth = -0.5 * R_new_A1x * Jr;
    if (F) {
      F->setIdentity();
      F->block<3, 3>(Idx::kDp, Idx::kDth) = dt2 * J_abar_th;
      F->block<3, 3>(Idx::kDp, Idx::kDv) = dt * I;
      F->block<3, 3>(Idx::kDp, Idx::kDab) = dt2 * J_abar_ab;
      F->block<3, 3>(Idx::kDp, Idx::kDwb) = dt2 * J_abar_wb;
      F->block<3, 3>(Idx::kDp, Idx::kDg) = dt2 * I;
      F->block<3, 3>(Idx::kDth, Idx::kDth) = dR_T;
      F->block<3, 3>(Idx::kDth, Idx::kDwb) = -dt * Jr;
      F->block<3, 3>(Idx::kDv, Idx::kDth) = dt * J_abar_th;
      F->block<3, 3>(Idx::kDv, Idx::kDab) = dt * J_abar_ab;
      F->block<3, 3>(Idx::kDv, Idx::kDwb) = dt * J_abar_wb;
      F->block<3, 3>(Idx::kDv, Idx::kDg) = dt * I;
    }
    if (G) {
      G->setZero();
      G->block<3, 3>(Idx::kDp, Idx::kNth) = dt2 * J_abar_nth;
      G->block<3, 3>(Idx::kDth, Idx::kNth) = Jr;
      G->block<3, 3>(Idx::kDv, Idx::kNth) = dt * J_abar_nth;
      G->block<3, 3>(Idx::kDv, Idx::kNv) = I;
      G->block<3, 3>(Idx::kDab, Idx::kNab) = I;
      G->block<3, 3>(Idx::kDwb, Idx::kNwb) = I;
    }
  }
  // Every input is read above, so x_out may alias x.
  x_out.segment<3>(Idx::kP) = p + v * dt + dt2 * a_bar;
  x_out.segment<4>(Idx::kQ) = math::quat_to_wxyz(q_new);
  x_out.segment<3>(Idx::kV) = v + a_bar * dt + noise.segment<3>(Idx::kNv);
  x_out.segment<3>(Idx::kAb) = a_b + noise.segment<3>(Idx::kNab);
  x_out.segment<3>(Idx::kWb) = w_b + noise.segment<3>(Idx::kNwb);
  x_out.segment<3>(Idx::kG) = g;
}

void inertial_predict(const Vector19d& x, const ImuMeasurement& imu_k, const ImuMeasurement& imu_k1, double dt,
                      const InertialParams& params, Vector19d& x_out, Matrix18d* F, Matrix18d* Q) {
  using Idx = InertialIndex;
  if (!Q) {
    inertial_step(x, imu_k, imu_k1, dt, Vector12d::Zero(), x_out, F, nullptr);
    return;
  }
  Matrix18x12d G;
  inertial_step(x, imu_k, imu_k1, dt, Vector12d::Zero(), x_out, F, &G);
  Vector12d n_var;
  n_var.segment<3>(Idx::kNth).setConstant(params.gyroscope_noise_density * params.gyroscope_noise_density * dt);
  n_var.segment<3>(Idx::kNv).setConstant(params.accelerometer_noise_density * params.accelerometer_noise_density * dt);
  n_var.segment<3>(Idx::kNab).setConstant(params.accelerometer_random_walk * params.accelerometer_random_walk * dt);
  n_var.segment<3>(Idx::kNwb).setConstant(params.gyroscope_random_walk * params.gyroscope_random_walk * dt);
  *Q = G * n_var.asDiagonal() * G.transpose();
  *Q = 0.5 * (*Q + Q->transpose()).eval();
}

}  // namespace rtslam::models
