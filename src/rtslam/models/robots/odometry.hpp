#pragma once
// Odometry-driven robot (RT-SLAM's RobotOdometry). State x = [p(3) q(4: w x y z)]: p = p_WR in W, q = q_WR.
// Ambient size 7, tangent size 6 ordered [δp δθ], retraction q ⊕ δθ = q ⊗ Exp(δθ) (right perturbation).
//
// Input: one odometry increment u = [dp dθ] between two odometry readings, both in the robot frame at the first
// reading: dp the displacement, dθ the rotation vector of R_{k}ᵀ R_{k+1}. Motion:
//   p⁺ = p + R(q) dp,   q⁺ = q ⊗ Exp(dθ).
// Jacobians on tangent spaces (J_out_in):
//   F = ∂x⁺/∂x: F_pp = I, F_pθ = −R [dp]×, F_θθ = R(Exp(dθ))ᵀ;
//   G = ∂x⁺/∂u: G_p,dp = R, G_θ,dθ = Jr(dθ).
// Input noise, white over the increment of duration dt (s), of independent components whose variances grow
// linearly with time and with the motion (a wheel's slip grows with the distance rolled):
//   U = diag((σ_p² dt + k_p² |dp|) I₃, (σ_θ² dt + k_θ² |dθ|) I₃),
// so that splitting an increment into parts splits U in the same proportions (OdometryIncrement::scaled).
#include <Eigen/Core>

namespace rtslam::models {

struct OdometryParams {
  double sigma_p = 0.01;      // translation noise density, m/√s
  double sigma_theta = 0.01;  // rotation noise density, rad/√s
  double k_p = 0.05;          // translation noise per distance travelled, m/√m (σ² = k_p² |dp|)
  double k_theta = 0.05;      // rotation noise per angle turned, rad/√rad (σ² = k_θ² |dθ|)
  /// Throws ConfigError naming the key (odometry/<key>) unless each is finite and in [0, 10].
  void validate() const;
};

using Vector7d = Eigen::Matrix<double, 7, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

struct OdometryIndex {
  static constexpr int kP = 0, kQ = 3;       // ambient offsets (size 7)
  static constexpr int kDp = 0, kDth = 3;    // tangent offsets (size 6)
  static constexpr int kAmbientSize = 7, kTangentSize = 6;
};

/// One increment [dp dθ] in R at its start, over dt seconds.
struct OdometryIncrement {
  Eigen::Vector3d dp = Eigen::Vector3d::Zero();
  Eigen::Vector3d dtheta = Eigen::Vector3d::Zero();
  double dt = 0.0;
  /// The fraction f ∈ [0, 1] of it (f dp, f dθ, f dt): a constant-twist split, exact for dθ, first order in
  /// |dθ||dp| for dp.
  OdometryIncrement scaled(double f) const { return {f * dp, f * dtheta, f * dt}; }
};

/// U (6×6, [dp dθ]) of an increment (header comment).
Matrix6d odometry_input_covariance(const OdometryIncrement& u, const OdometryParams& params);

/// x_out = f(x, u). F = ∂x⁺/∂x, G = ∂x⁺/∂u (6×6 each). The output quaternion is unit norm; x and x_out may alias.
void odometry_predict(const Vector7d& x, const OdometryIncrement& u, Vector7d& x_out, Matrix6d* F = nullptr,
                      Matrix6d* G = nullptr);

}  // namespace rtslam::models
