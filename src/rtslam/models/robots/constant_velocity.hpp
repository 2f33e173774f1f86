#pragma once
// Constant-velocity robot (../shared/MATH.md, "Robots"). State x = [p(3) q(4: w x y z) v(3) ω(3)]: p = p_WR and
// v = v_WR in W, q = q_WR, ω the angular rate in the robot frame R. Ambient size 13, tangent size 12 ordered
// [δp δθ δv δω], with the orientation retraction q ⊕ δθ = q ⊗ Exp(δθ) (right perturbation).
//
// Motion over dt (s): p⁺ = p + v dt, q⁺ = q ⊗ Exp(ω dt), v⁺ = v + n_v, ω⁺ = ω + n_ω, with white perturbations
// given as continuous-time densities: n_v ~ N(0, σ_v² dt I), n_ω ~ N(0, σ_ω² dt I) (variances grow linearly
// with dt). Tangent Jacobian F = ∂x⁺/∂x:
//   F_pp = I, F_pv = dt I, F_θθ = R(Exp(ω dt))ᵀ, F_θω = Jr(ω dt) dt, F_vv = F_ωω = I (other blocks 0).
#include <Eigen/Core>

namespace rtslam::models {

struct ConstantVelocityParams {
  double sigma_v = 2.0;  // linear velocity perturbation density, m/s/√s
  double sigma_w = 2.0;  // angular velocity perturbation density, rad/s/√s
  /// Throws ConfigError naming the value unless both are finite and >= 0.
  void validate() const;
};

using Vector13d = Eigen::Matrix<double, 13, 1>;
using Matrix12d = Eigen::Matrix<double, 12, 12>;

/// Ambient and tangent indices of the state blocks.
struct ConstantVelocityIndex {
  static constexpr int kP = 0, kQ = 3, kV = 7, kW = 10;      // ambient offsets (size 13)
  static constexpr int kDp = 0, kDth = 3, kDv = 6, kDw = 9;  // tangent offsets (size 12)
  static constexpr int kAmbientSize = 13, kTangentSize = 12;
};

/// x_out = f(x, dt) (dt >= 0, seconds). F (12x12) = ∂x⁺/∂x on tangent spaces; Q (12x12) the discrete process noise
/// covariance (σ² dt on the v and ω rows). The output quaternion is unit norm. x and x_out may alias.
void constant_velocity_predict(const Vector13d& x, double dt, const ConstantVelocityParams& params, Vector13d& x_out,
                               Matrix12d* F = nullptr, Matrix12d* Q = nullptr);

}  // namespace rtslam::models
