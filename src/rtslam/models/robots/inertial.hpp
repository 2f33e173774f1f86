#pragma once
// Inertial robot driven by IMU samples (../shared/MATH.md, "Robots", inertial, midpoint step).
//
// State x = [p(3) q(4: w x y z) v(3) a_b(3) ω_b(3) g(3)]: p = p_WR, v = v_WR and g (gravity, estimated as a vector)
// in W, q = q_WR, a_b and ω_b the accelerometer and gyro biases in R (the IMU body frame). Ambient size 19, tangent
// size 18 ordered [δp δθ δv δa_b δω_b δg], with q ⊕ δθ = q ⊗ Exp(δθ) (right perturbation).
//
// IMU samples (a_m, ω_m) are instantaneous values at their timestamps; one step integrates from sample k to k+1
// over dt = t_{k+1} − t_k (never holding one sample over the interval):
//   ω̄ = ½(ω_k + ω_{k+1}) − ω_b,  q⁺ = q ⊗ Exp(ω̄ dt + n_θ),
//   ā = ½(R(q)(a_k − a_b) + R(q⁺)(a_{k+1} − a_b)) + g,
//   p⁺ = p + v dt + ½ ā dt²,  v⁺ = v + ā dt + n_v,  a_b⁺ = a_b + n_ab,  ω_b⁺ = ω_b + n_ωb,  g⁺ = g,
// with n_θ ~ N(0, σ_g² dt I), n_v ~ N(0, σ_a² dt I), n_ab ~ N(0, σ_ab² dt I), n_ωb ~ N(0, σ_gb² dt I).
// The accelerometer measures specific force: a_m = R(q)ᵀ(a_W − g) + a_b (at rest, −R(q)ᵀ g + a_b).
// The noise is mapped through the step's Jacobians: Q = G N Gᵀ with G = ∂x⁺/∂[n_θ n_v n_ab n_ωb] (18x12), so
// the attitude noise also reaches v and p through R(q⁺).
#include <Eigen/Core>

namespace rtslam::models {

/// Continuous-time IMU noise densities; the names and units of EuRoC's sensor.yaml (defaults: its ADIS16448).
struct InertialParams {
  double accelerometer_noise_density = 2.0e-3;  // σ_a, m/s²/√Hz
  double gyroscope_noise_density = 1.6968e-4;   // σ_g, rad/s/√Hz
  double accelerometer_random_walk = 3.0e-3;    // σ_ab, m/s³/√Hz
  double gyroscope_random_walk = 1.9393e-5;     // σ_gb, rad/s²/√Hz
  /// Throws ConfigError naming the key and value unless all are finite and >= 0.
  void validate() const;
};

/// One IMU reading: specific force (m/s²) and angular rate (rad/s), both in the IMU frame R.
struct ImuMeasurement {
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
};

using Vector19d = Eigen::Matrix<double, 19, 1>;
using Matrix18d = Eigen::Matrix<double, 18, 18>;
using Matrix18x12d = Eigen::Matrix<double, 18, 12>;
using Vector12d = Eigen::Matrix<double, 12, 1>;

/// Ambient and tangent indices of the state blocks, and of the noise vector [n_θ n_v n_ab n_ωb].
struct InertialIndex {
  static constexpr int kP = 0, kQ = 3, kV = 7, kAb = 10, kWb = 13, kG = 16;        // ambient (size 19)
  static constexpr int kDp = 0, kDth = 3, kDv = 6, kDab = 9, kDwb = 12, kDg = 15;  // tangent (size 18)
  static constexpr int kNth = 0, kNv = 3, kNab = 6, kNwb = 9;                      // noise (size 12)
  static constexpr int kAmbientSize = 19, kTangentSize = 18, kNoiseSize = 12;
};

/// One midpoint step with an explicit noise sample n = [n_θ n_v n_ab n_ωb] (zero for the mean prediction).
/// F = ∂x⁺/∂x (18x18) and G = ∂x⁺/∂n (18x12) on tangent spaces, at the given n. x and x_out may alias.
void inertial_step(const Vector19d& x, const ImuMeasurement& imu_k, const ImuMeasurement& imu_k1, double dt,
                   const Vector12d& noise, Vector19d& x_out, Matrix18d* F = nullptr, Matrix18x12d* G = nullptr);

/// The mean prediction over dt >= 0 (s) between two IMU samples: x_out = f(x, 0), F (18x18) its tangent Jacobian and
/// Q (18x18) = G N Gᵀ the discrete process noise, N = diag(σ_g² dt I, σ_a² dt I, σ_ab² dt I, σ_gb² dt I).
/// x and x_out may alias.
void inertial_predict(const Vector19d& x, const ImuMeasurement& imu_k, const ImuMeasurement& imu_k1, double dt,
                      const InertialParams& params, Vector19d& x_out, Matrix18d* F = nullptr, Matrix18d* Q = nullptr);

}  // namespace rtslam::models
