#include "rtslam/pipeline/inertial_init.hpp"

#include <cmath>
#include <tuple>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/io/source.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::pipeline {

using models::InertialIndex;

void InertialOptions::validate() const {
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
  // Priors and scales: positive, and below values no start or IMU could mean (a unit slip otherwise).
  for (const auto& [key, v, hi, unit] :
       {std::tuple{"velocity_std_standstill", velocity_std_standstill, 100.0, "m/s"},
        std::tuple{"velocity_std_motion", velocity_std_motion, 100.0, "m/s"},
        std::tuple{"accel_bias_std", accel_bias_std, 10.0, "m/s²"},
        std::tuple{"gyro_bias_std", gyro_bias_std, 1.0, "rad/s"},
        std::tuple{"gravity_std_standstill", gravity_std_standstill, 10.0, "m/s²"},
        std::tuple{"gravity_std_motion", gravity_std_motion, 10.0, "m/s²"},
        std::tuple{"gravity_magnitude_std", gravity_magnitude_std, 1.0, "m/s²"},
        std::tuple{"noise_scale", noise_scale, 1000.0, ""}, std::tuple{"random_walk_scale", random_walk_scale, 1000.0, ""},
        std::tuple{"extrinsics_std_m", extrinsics_std_m, 1.0, "m"},
        std::tuple{"extrinsics_std_deg", extrinsics_std_deg, 90.0, "deg"}}) {
    require_bound(v > 0.0 && v <= hi, w, key, v, fmt::format("in (0, {:g}]{}{}", hi, *unit ? " " : "", unit));
  }
  for (const auto& [key, v] : {std::pair{"accelerometer_noise_density", accelerometer_noise_density},
                               std::pair{"gyroscope_noise_density", gyroscope_noise_density},
                               std::pair{"accelerometer_random_walk", accelerometer_random_walk},
                               std::pair{"gyroscope_random_walk", gyroscope_random_walk}}) {
    if (v) require_bound(*v > 0.0 && *v < 10.0, w, key, *v, "in (0, 10)");
  }
  vi_init.validate();
  calibration_check.validate();
  if (time_offset_s) require_bound(std::abs(*time_offset_s) < 1.0, w, "time_offset", *time_offset_s, "within ±1 s");
  if (gyro_saturation) {
    require_bound(*gyro_saturation > 0.0 && *gyro_saturation <= io::ImuRange::kMaxPlausibleGyro, w, "gyro_saturation",
                  *gyro_saturation, fmt::format("in (0, {:g}] rad/s", io::ImuRange::kMaxPlausibleGyro));
  }
  if (accel_saturation) {
    require_bound(*accel_saturation > 0.0 && *accel_saturation <= io::ImuRange::kMaxPlausibleAccel, w,
                  "accel_saturation", *accel_saturation,
                  fmt::format("in (0, {:g}] m/s²", io::ImuRange::kMaxPlausibleAccel));
  }
}

void ViInitOptions::validate() const {
  const std::string w = "imu/vi_init";
  require_bound(window_s > 0.0 && window_s <= 5.0, w, "window", window_s, "in (0, 5] s");
  require_bound(max_window_s >= window_s && max_window_s <= 10.0, w, "max_window", max_window_s,
                "in [window, 10] s");
  require_bound(min_excitation_m >= 0.0 && min_excitation_m < 10.0, w, "min_excitation_m", min_excitation_m,
                "in [0, 10) m");
  require_bound(max_wait_s >= 0.0 && max_wait_s <= 60.0, w, "max_wait", max_wait_s, "in [0, 60] s");
  require_bound(min_frames >= 3 && min_frames <= 500, w, "min_frames", min_frames, "in [3, 500]");
  require_bound(min_track_frames >= 3 && min_track_frames <= 500, w, "min_track_frames", min_track_frames,
                "in [3, 500]");
  require_bound(cells_x >= 1 && cells_x <= 64, w, "cells_x", cells_x, "in [1, 64]");
  require_bound(cells_y >= 1 && cells_y <= 64, w, "cells_y", cells_y, "in [1, 64]");
  require_bound(patch_size >= 5 && patch_size <= 41 && patch_size % 2 == 1, w, "patch_size", patch_size,
                "odd, in [5, 41]");
  require_bound(min_score > 0.0 && min_score < 1.0, w, "min_score", min_score, "in (0, 1)");
  require_bound(search_px >= 2.0 && search_px <= 200.0, w, "search_px", search_px, "in [2, 200] px");
  require_bound(min_features >= 4 && min_features <= 4096, w, "min_features", min_features, "in [4, 4096]");
  require_bound(standstill_max_disparity_px > 0.0 && standstill_max_disparity_px < 100.0, w,
                "standstill_max_disparity_px", standstill_max_disparity_px, "in (0, 100) px");
  require_bound(min_parallax_px > 0.0 && min_parallax_px < 1000.0, w, "min_parallax_px", min_parallax_px,
                "in (0, 1000) px");
  require_bound(max_reprojection_px > 0.0 && max_reprojection_px < 100.0, w, "max_reprojection_px",
                max_reprojection_px, "in (0, 100) px");
  require_bound(gravity > 1.0 && gravity < 30.0, w, "gravity", gravity, "in (1, 30) m/s²");
  require_bound(max_speed > 0.0 && max_speed <= 1e4, w, "max_speed", max_speed, "in (0, 1e4] m/s");
  require_bound(max_split_gravity_deg > 0.0 && max_split_gravity_deg <= 90.0, w, "max_split_gravity_deg",
                max_split_gravity_deg, "in (0, 90] deg");
  require_bound(max_split_velocity_ratio > 0.0 && max_split_velocity_ratio <= 10.0, w, "max_split_velocity_ratio",
                max_split_velocity_ratio, "in (0, 10]");
  require_bound(accel_bias_std > 0.0 && accel_bias_std <= 10.0, w, "accel_bias_std", accel_bias_std,
                "in (0, 10] m/s²");
}

void read_vi_init(YamlMap m, ViInitOptions& o) {
  m.get("enabled", o.enabled);
  m.get("window", o.window_s);
  m.get("max_wait", o.max_wait_s);
  m.get("max_window", o.max_window_s);
  m.get("min_excitation_m", o.min_excitation_m);
  m.get("min_frames", o.min_frames);
  m.get("min_track_frames", o.min_track_frames);
  m.get("cells_x", o.cells_x);
  m.get("cells_y", o.cells_y);
  m.get("patch_size", o.patch_size);
  m.get("min_score", o.min_score);
  m.get("search_px", o.search_px);
  m.get("min_features", o.min_features);
  m.get("standstill_max_disparity_px", o.standstill_max_disparity_px);
  m.get("min_parallax_px", o.min_parallax_px);
  m.get("max_reprojection_px", o.max_reprojection_px);
  m.get("gravity", o.gravity);
  m.get("max_speed", o.max_speed);
  m.get("max_split_gravity_deg", o.max_split_gravity_deg);
  m.get("max_split_velocity_ratio", o.max_split_velocity_ratio);
  m.get("refine_gyro_bias", o.refine_gyro_bias);
  m.get("accel_bias_std", o.accel_bias_std);
  m.finish();
}

YAML::Node vi_init_to_yaml(const ViInitOptions& o) {
  YAML::Node n;
  n["enabled"] = o.enabled;
  n["window"] = o.window_s;
  n["max_wait"] = o.max_wait_s;
  n["max_window"] = o.max_window_s;
  n["min_excitation_m"] = o.min_excitation_m;
  n["min_frames"] = o.min_frames;
  n["min_track_frames"] = o.min_track_frames;
  n["cells_x"] = o.cells_x;
  n["cells_y"] = o.cells_y;
  n["patch_size"] = o.patch_size;
  n["min_score"] = o.min_score;
  n["search_px"] = o.search_px;
  n["min_features"] = o.min_features;
  n["standstill_max_disparity_px"] = o.standstill_max_disparity_px;
  n["min_parallax_px"] = o.min_parallax_px;
  n["max_reprojection_px"] = o.max_reprojection_px;
  n["gravity"] = o.gravity;
  n["max_speed"] = o.max_speed;
  n["max_split_gravity_deg"] = o.max_split_gravity_deg;
  n["max_split_velocity_ratio"] = o.max_split_velocity_ratio;
  n["refine_gyro_bias"] = o.refine_gyro_bias;
  n["accel_bias_std"] = o.accel_bias_std;
  return n;
}

void read_inertial(YamlMap m, InertialOptions& o) {
  m.get("init", o.init);
  m.get("init_window", o.init_window_s);
  m.get("standstill_max_gyro_std", o.standstill_max_gyro_std);
  m.get("standstill_max_accel_std", o.standstill_max_accel_std);
  m.get("velocity_std_standstill", o.velocity_std_standstill);
  m.get("velocity_std_motion", o.velocity_std_motion);
  m.get("accel_bias_std", o.accel_bias_std);
  m.get("gyro_bias_std", o.gyro_bias_std);
  m.get("gravity_std_standstill", o.gravity_std_standstill);
  m.get("gravity_std_motion", o.gravity_std_motion);
  m.get("gravity_magnitude", o.gravity_magnitude);
  m.get("gravity_magnitude_std", o.gravity_magnitude_std);
  m.get("noise_scale", o.noise_scale);
  m.get("random_walk_scale", o.random_walk_scale);
  m.get("estimate_extrinsics", o.estimate_extrinsics);
  m.get("extrinsics_std_m", o.extrinsics_std_m);
  m.get("extrinsics_std_deg", o.extrinsics_std_deg);
  if (m.has("vi_init")) read_vi_init(m.child("vi_init"), o.vi_init);
  if (m.has("calibration_check")) {
    YamlMap c = m.child("calibration_check");
    o.calibration_check = calib::CheckOptions::from_yaml(c);
  }
  double v = 0.0;
  if (m.has("time_offset")) { m.get("time_offset", v); o.time_offset_s = v; }
  if (m.has("accelerometer_noise_density")) { m.get("accelerometer_noise_density", v); o.accelerometer_noise_density = v; }
  if (m.has("gyroscope_noise_density")) { m.get("gyroscope_noise_density", v); o.gyroscope_noise_density = v; }
  if (m.has("accelerometer_random_walk")) { m.get("accelerometer_random_walk", v); o.accelerometer_random_walk = v; }
  if (m.has("gyroscope_random_walk")) { m.get("gyroscope_random_walk", v); o.gyroscope_random_walk = v; }
  if (m.has("gyro_saturation")) { m.get("gyro_saturation", v); o.gyro_saturation = v; }
  if (m.has("accel_saturation")) { m.get("accel_saturation", v); o.accel_saturation = v; }
  m.finish();
}

YAML::Node inertial_to_yaml(const InertialOptions& o) {
  YAML::Node n;
  n["init"] = o.init;
  n["init_window"] = o.init_window_s;
  n["standstill_max_gyro_std"] = o.standstill_max_gyro_std;
  n["standstill_max_accel_std"] = o.standstill_max_accel_std;
  n["velocity_std_standstill"] = o.velocity_std_standstill;
  n["velocity_std_motion"] = o.velocity_std_motion;
  n["accel_bias_std"] = o.accel_bias_std;
  n["gyro_bias_std"] = o.gyro_bias_std;
  n["gravity_std_standstill"] = o.gravity_std_standstill;
  n["gravity_std_motion"] = o.gravity_std_motion;
  n["gravity_magnitude"] = o.gravity_magnitude;
  n["gravity_magnitude_std"] = o.gravity_magnitude_std;
  n["noise_scale"] = o.noise_scale;
  n["random_walk_scale"] = o.random_walk_scale;
  n["estimate_extrinsics"] = o.estimate_extrinsics;
  n["extrinsics_std_m"] = o.extrinsics_std_m;
  n["extrinsics_std_deg"] = o.extrinsics_std_deg;
  n["vi_init"] = vi_init_to_yaml(o.vi_init);
  n["calibration_check"] = o.calibration_check.to_yaml();
  if (o.time_offset_s) n["time_offset"] = *o.time_offset_s;
  if (o.accelerometer_noise_density) n["accelerometer_noise_density"] = *o.accelerometer_noise_density;
  if (o.gyroscope_noise_density) n["gyroscope_noise_density"] = *o.gyroscope_noise_density;
  if (o.accelerometer_random_walk) n["accelerometer_random_walk"] = *o.accelerometer_random_walk;
  if (o.gyroscope_random_walk) n["gyroscope_random_walk"] = *o.gyroscope_random_walk;
  if (o.gyro_saturation) n["gyro_saturation"] = *o.gyro_saturation;
  if (o.accel_saturation) n["accel_saturation"] = *o.accel_saturation;
  return n;
}

models::InertialParams inertial_params(const std::optional<io::ImuCalibration>& imu, const InertialOptions& o,
                                       const std::string& dataset) {
  if (!imu) throw ConfigError(fmt::format("slam/robot = inertial: dataset '{}' has no IMU", dataset));
  models::InertialParams p;
  p.accelerometer_noise_density = o.accelerometer_noise_density.value_or(imu->accel_noise_density) * o.noise_scale;
  p.gyroscope_noise_density = o.gyroscope_noise_density.value_or(imu->gyro_noise_density) * o.noise_scale;
  p.accelerometer_random_walk = o.accelerometer_random_walk.value_or(imu->accel_random_walk) * o.random_walk_scale;
  p.gyroscope_random_walk = o.gyroscope_random_walk.value_or(imu->gyro_random_walk) * o.random_walk_scale;
  if (p.accelerometer_noise_density <= 0.0 || p.gyroscope_noise_density <= 0.0) {
    throw ConfigError(fmt::format("dataset '{}': the IMU calibration has no noise densities", dataset));
  }
  p.validate();
  return p;
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

void constrain_gravity_magnitude(InertialStart& s, const InertialOptions& o) {
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

Eigen::Matrix<double, 18, 18> motion_prior_covariance(const InertialOptions& o, const Eigen::Matrix3d& R_WR) {
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

InertialStart initialize_inertial(const std::vector<ImuWindowSample>& window, TimeNs t, const InertialOptions& o) {
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

}  // namespace rtslam::pipeline
