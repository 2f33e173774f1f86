#include "rtslam/strategies/inertial_start.hpp"

#include <algorithm>
#include <cmath>
#include <tuple>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::strategies {

using models::InertialIndex;

void InertialStartOptions::validate() const {
  const std::string w = "imu";
  if (init != "auto" && init != "standstill" && init != "motion") {
    throw ConfigError(fmt::format("imu/init = '{}' must be auto, standstill or motion", init));
  }
  require_bound(gravity_magnitude >= 9.7 && gravity_magnitude <= 9.9, w, "gravity_magnitude", gravity_magnitude,
                "in [9.7, 9.9] m/s² (Earth)");
  require_bound(init_window_s > 0.0 && init_window_s <= 10.0, w, "init_window", init_window_s, "in (0, 10] s");
  require_bound(standstill_max_gyro_std > 0.0 && standstill_max_gyro_std <= 10.0, w, "standstill_max_gyro_std",
                standstill_max_gyro_std, "in (0, 10] rad/s");
  require_bound(standstill_max_accel_std > 0.0 && standstill_max_accel_std <= 100.0, w, "standstill_max_accel_std",
                standstill_max_accel_std, "in (0, 100] m/s²");
  // Priors: positive, and below values no start could mean (a unit slip otherwise).
  for (const auto& [key, v, hi, unit] :
       {std::tuple{"velocity_std_standstill", velocity_std_standstill, 100.0, "m/s"},
        std::tuple{"velocity_std_motion", velocity_std_motion, 100.0, "m/s"},
        std::tuple{"accel_bias_std", accel_bias_std, 10.0, "m/s²"},
        std::tuple{"gyro_bias_std", gyro_bias_std, 1.0, "rad/s"},
        std::tuple{"gravity_std_standstill", gravity_std_standstill, 10.0, "m/s²"},
        std::tuple{"gravity_std_motion", gravity_std_motion, 10.0, "m/s²"},
        std::tuple{"gravity_magnitude_std", gravity_magnitude_std, 1.0, "m/s²"}}) {
    require_bound(v > 0.0 && v <= hi, w, key, v, fmt::format("in (0, {:g}] {}", hi, unit));
  }
}

std::string InertialStart::describe() const {
  const Eigen::Vector3d g = x.segment<3>(InertialIndex::kG);
  const std::string kind = standstill ? "standstill" : "in-motion";
  const std::string from = samples > 0 ? fmt::format(" from {} IMU samples (gyro std {:.3f} rad/s, accel std {:.3f} m/s²)",
                                                     samples, gyro_std, accel_std)
                                       : std::string();
  return fmt::format("{} start{}: |g| = {:.3f} m/s², gyro bias ({:.4f}, {:.4f}, {:.4f}) rad/s", kind, from, g.norm(),
                     x[InertialIndex::kWb], x[InertialIndex::kWb + 1], x[InertialIndex::kWb + 2]);
}

// The prior of [v a_b ω_b g] with g = −R f̄, f̄ = mean(R_k (f_k − a_b)) + a_b: g's error is the accelerometer bias error
// rotated into W (correlated with a_b: ∂g/∂a_b = R) plus g_std (the spread of the mean, or the unknown mean
// acceleration in motion).
Eigen::Matrix<double, 18, 18> prior_covariance(double v_std, double ab_std, double wb_std, double g_std,
                                               const Eigen::Matrix3d& R) {
  using I = InertialIndex;
  Eigen::Matrix<double, 18, 18> P = Eigen::Matrix<double, 18, 18>::Zero();
  P.block<3, 3>(I::kDv, I::kDv) = v_std * v_std * Eigen::Matrix3d::Identity();
  P.block<3, 3>(I::kDab, I::kDab) = ab_std * ab_std * Eigen::Matrix3d::Identity();
  P.block<3, 3>(I::kDwb, I::kDwb) = wb_std * wb_std * Eigen::Matrix3d::Identity();
  P.block<3, 3>(I::kDg, I::kDg) = (g_std * g_std + ab_std * ab_std) * Eigen::Matrix3d::Identity();
  P.block<3, 3>(I::kDg, I::kDab) = ab_std * ab_std * R;
  P.block<3, 3>(I::kDab, I::kDg) = P.block<3, 3>(I::kDg, I::kDab).transpose();
  return P;
}

void constrain_gravity_magnitude(InertialStart& s, const InertialStartOptions& o) {
  using I = InertialIndex;
  const Eigen::Vector3d g = s.x.segment<3>(I::kG);
  if (!(g.norm() > 0.0) || !(o.gravity_magnitude_std > 0.0)) return;
  Eigen::Matrix<double, 1, 18> H = Eigen::Matrix<double, 1, 18>::Zero();
  H.segment<3>(I::kDg) = g.normalized().transpose();
  const double S = (H * s.P * H.transpose())(0, 0) + o.gravity_magnitude_std * o.gravity_magnitude_std;
  const Eigen::Matrix<double, 18, 1> K = s.P * H.transpose() / S;
  const Eigen::Matrix<double, 18, 1> dx = K * (o.gravity_magnitude - g.norm());
  // p and q are the gauge (zero covariance, so zero gain); the other blocks are additive.
  s.x.segment<3>(I::kV) += dx.segment<3>(I::kDv);
  s.x.segment<3>(I::kAb) += dx.segment<3>(I::kDab);
  s.x.segment<3>(I::kWb) += dx.segment<3>(I::kDwb);
  s.x.segment<3>(I::kG) += dx.segment<3>(I::kDg);
  s.P -= K * S * K.transpose();
  s.P = 0.5 * (s.P + s.P.transpose());
}

Eigen::Matrix<double, 18, 18> motion_prior_covariance(const InertialStartOptions& o, const Eigen::Matrix3d& R_WR) {
  return prior_covariance(o.velocity_std_motion, o.accel_bias_std, o.gyro_bias_std, o.gravity_std_motion, R_WR);
}

Eigen::Quaterniond gravity_aligned_attitude(const Eigen::Vector3d& f_R) {
  const Eigen::Vector3d z = f_R.normalized();  // W's z axis (up) in R
  int k = 0;                                   // the body axis most orthogonal to z
  z.cwiseAbs().minCoeff(&k);
  const Eigen::Vector3d x = (Eigen::Vector3d::Unit(k) - z * z[k]).normalized();  // W's x axis in R
  Eigen::Matrix3d R_RW;
  R_RW.col(0) = x;
  R_RW.col(1) = z.cross(x);
  R_RW.col(2) = z;
  return Eigen::Quaterniond(R_RW.transpose()).normalized();  // R_WR
}

InertialStart initialize_inertial(const std::vector<ImuWindowSample>& window, TimeNs t, const InertialStartOptions& o) {
  const TimeNs t0 = t - from_seconds(o.init_window_s);
  std::vector<const ImuWindowSample*> in;
  Eigen::Vector3d sa = Eigen::Vector3d::Zero(), sw = Eigen::Vector3d::Zero();
  Eigen::Vector3d qa = Eigen::Vector3d::Zero(), qw = Eigen::Vector3d::Zero();
  for (const auto& s : window) {
    if (s.t < t0 || s.t > t) continue;
    in.push_back(&s);
    sa += s.m.accel;
    sw += s.m.gyro;
    qa += s.m.accel.cwiseAbs2();
    qw += s.m.gyro.cwiseAbs2();
  }
  const int n = static_cast<int>(in.size());
  if (n < 10) {
    throw DataError(fmt::format("inertial initialization at t = {} ns: {} IMU samples in the {:.2f} s window, need 10",
                                t, n, o.init_window_s));
  }
  InertialStart s;
  s.samples = n;
  const Eigen::Vector3d mean_a = sa / n, mean_w = sw / n;
  const Eigen::Vector3d var_a = (qa / n - mean_a.cwiseAbs2()).cwiseMax(0.0);
  const Eigen::Vector3d var_w = (qw / n - mean_w.cwiseAbs2()).cwiseMax(0.0);
  s.accel_std = std::sqrt(var_a.sum());
  s.gyro_std = std::sqrt(var_w.sum());
  s.standstill = o.init == "standstill" ||
                 (o.init == "auto" && s.gyro_std < o.standstill_max_gyro_std && s.accel_std < o.standstill_max_accel_std);

  using I = InertialIndex;
  auto& x = s.x;
  if (s.standstill) x.segment<3>(I::kWb) = mean_w;
  // The mean specific force in R at t: the accelerometer measures f = Rᵀ(a − g) + a_b; each sample is rotated to
  // the attitude at t by the gyro integrated over the window (midpoint rule, backwards from t), so rotation during
  // the window does not tilt the estimate. At standstill −f is gravity; in motion it is off by the window's mean
  // acceleration, which the gravity prior covers.
  const Eigen::Vector3d w_b = x.segment<3>(I::kWb);
  Eigen::Matrix3d R_t_k = Eigen::Matrix3d::Identity();  // R_{R(t) R(t_k)}
  Eigen::Vector3d f_R = in.back()->m.accel;
  for (int k = n - 2; k >= 0; --k) {
    const auto& a = *in[static_cast<std::size_t>(k)];
    const auto& b = *in[static_cast<std::size_t>(k + 1)];
    const Eigen::Vector3d w = 0.5 * (a.m.gyro + b.m.gyro) - w_b;
    R_t_k = R_t_k * math::exp_so3(w * to_seconds(b.t - a.t)).toRotationMatrix().transpose();
    f_R += R_t_k * a.m.accel;
  }
  f_R /= n;
  if (!(f_R.norm() > 1e-3) || !f_R.allFinite()) {
    throw DataError(fmt::format("inertial initialization at t = {} ns: the mean specific force ({:.3g} m/s²) gives no "
                                "gravity direction (free fall, or an accelerometer reading zeros)", t, f_R.norm()));
  }
  const Eigen::Quaterniond q_WR = gravity_aligned_attitude(f_R);
  x.segment<4>(I::kQ) = math::quat_to_wxyz(q_WR);
  const Eigen::Matrix3d R = q_WR.toRotationMatrix();
  x.segment<3>(I::kG) = -(R * f_R);
  const double v_std = s.standstill ? o.velocity_std_standstill : o.velocity_std_motion;
  const double wb_std = s.standstill ? std::max(1e-3, s.gyro_std / std::sqrt(static_cast<double>(n))) : o.gyro_bias_std;
  const double g_std = s.standstill ? o.gravity_std_standstill : o.gravity_std_motion;
  s.P = prior_covariance(v_std, o.accel_bias_std, wb_std, g_std, R);
  constrain_gravity_magnitude(s, o);
  return s;
}

}  // namespace rtslam::strategies
