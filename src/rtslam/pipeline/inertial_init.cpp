#include "rtslam/pipeline/inertial_init.hpp"

#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::pipeline {

using models::InertialIndex;

void InertialOptions::validate() const {
  const std::string w = "imu";
  if (init != "auto" && init != "standstill" && init != "motion") {
    throw ConfigError(fmt::format("imu/init = '{}' must be auto, standstill or motion", init));
  }
  require_bound(init_window_s > 0.0 && init_window_s <= 10.0, w, "init_window", init_window_s, "in (0, 10] s");
  require_bound(standstill_max_gyro_std > 0.0, w, "standstill_max_gyro_std", standstill_max_gyro_std, "> 0");
  require_bound(standstill_max_accel_std > 0.0, w, "standstill_max_accel_std", standstill_max_accel_std, "> 0");
  for (const auto& [key, v] : {std::pair{"velocity_std_standstill", velocity_std_standstill},
                               std::pair{"velocity_std_motion", velocity_std_motion},
                               std::pair{"velocity_std_groundtruth", velocity_std_groundtruth},
                               std::pair{"accel_bias_std", accel_bias_std}, std::pair{"gyro_bias_std", gyro_bias_std},
                               std::pair{"gravity_std_standstill", gravity_std_standstill},
                               std::pair{"gravity_std_motion", gravity_std_motion},
                               std::pair{"noise_scale", noise_scale},
                               std::pair{"random_walk_scale", random_walk_scale},
                               std::pair{"extrinsics_std_m", extrinsics_std_m},
                               std::pair{"extrinsics_std_deg", extrinsics_std_deg}}) {
    require_bound(v > 0.0, w, key, v, "> 0");
  }
  if (time_offset_s) require_bound(std::abs(*time_offset_s) < 1.0, w, "time_offset", *time_offset_s, "within ±1 s");
  if (gyro_saturation) require_bound(*gyro_saturation > 0.0, w, "gyro_saturation", *gyro_saturation, "> 0 rad/s");
  if (accel_saturation) require_bound(*accel_saturation > 0.0, w, "accel_saturation", *accel_saturation, "> 0 m/s²");
}

void read_inertial(YamlMap m, InertialOptions& o) {
  m.get("init", o.init);
  m.get("init_window", o.init_window_s);
  m.get("standstill_max_gyro_std", o.standstill_max_gyro_std);
  m.get("standstill_max_accel_std", o.standstill_max_accel_std);
  m.get("velocity_std_standstill", o.velocity_std_standstill);
  m.get("velocity_std_motion", o.velocity_std_motion);
  m.get("velocity_std_groundtruth", o.velocity_std_groundtruth);
  m.get("accel_bias_std", o.accel_bias_std);
  m.get("gyro_bias_std", o.gyro_bias_std);
  m.get("gravity_std_standstill", o.gravity_std_standstill);
  m.get("gravity_std_motion", o.gravity_std_motion);
  m.get("biases_from_groundtruth", o.biases_from_groundtruth);
  m.get("noise_scale", o.noise_scale);
  m.get("random_walk_scale", o.random_walk_scale);
  m.get("estimate_extrinsics", o.estimate_extrinsics);
  m.get("extrinsics_std_m", o.extrinsics_std_m);
  m.get("extrinsics_std_deg", o.extrinsics_std_deg);
  double v = 0.0;
  if (m.has("time_offset")) { m.get("time_offset", v); o.time_offset_s = v; }
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
  n["velocity_std_groundtruth"] = o.velocity_std_groundtruth;
  n["accel_bias_std"] = o.accel_bias_std;
  n["gyro_bias_std"] = o.gyro_bias_std;
  n["gravity_std_standstill"] = o.gravity_std_standstill;
  n["gravity_std_motion"] = o.gravity_std_motion;
  n["biases_from_groundtruth"] = o.biases_from_groundtruth;
  n["noise_scale"] = o.noise_scale;
  n["random_walk_scale"] = o.random_walk_scale;
  n["estimate_extrinsics"] = o.estimate_extrinsics;
  n["extrinsics_std_m"] = o.extrinsics_std_m;
  n["extrinsics_std_deg"] = o.extrinsics_std_deg;
  if (o.time_offset_s) n["time_offset"] = *o.time_offset_s;
  if (o.gyro_saturation) n["gyro_saturation"] = *o.gyro_saturation;
  if (o.accel_saturation) n["accel_saturation"] = *o.accel_saturation;
  return n;
}

models::InertialParams inertial_params(const std::optional<io::ImuCalibration>& imu, const InertialOptions& o,
                                       const std::string& dataset) {
  if (!imu) throw ConfigError(fmt::format("slam/robot = inertial: dataset '{}' has no IMU", dataset));
  models::InertialParams p;
  p.accelerometer_noise_density = imu->accel_noise_density * o.noise_scale;
  p.gyroscope_noise_density = imu->gyro_noise_density * o.noise_scale;
  p.accelerometer_random_walk = imu->accel_random_walk * o.random_walk_scale;
  p.gyroscope_random_walk = imu->gyro_random_walk * o.random_walk_scale;
  if (p.accelerometer_noise_density <= 0.0 || p.gyroscope_noise_density <= 0.0) {
    throw ConfigError(fmt::format("dataset '{}': the IMU calibration has no noise densities", dataset));
  }
  p.validate();
  return p;
}

std::string InertialStart::describe() const {
  const Eigen::Vector3d g = x.segment<3>(InertialIndex::kG);
  return fmt::format("{} start from {} IMU samples (gyro std {:.3f} rad/s, accel std {:.3f} m/s²): |g| = {:.3f} m/s², "
                     "gyro bias ({:.4f}, {:.4f}, {:.4f}) rad/s",
                     standstill ? "standstill" : "in-motion", samples, gyro_std, accel_std, g.norm(),
                     x[InertialIndex::kWb], x[InertialIndex::kWb + 1], x[InertialIndex::kWb + 2]);
}

InertialStart initialize_inertial(const std::vector<ImuWindowSample>& window, TimeNs t, const InertialOptions& o,
                                  const StampedPose* gt, const StampedPose* gt_start) {
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
  x.segment<4>(I::kQ) << 1.0, 0.0, 0.0, 0.0;
  const bool gt_biases = o.biases_from_groundtruth && gt && gt->gyro_bias && gt->accel_bias;
  if (gt) {
    x.segment<3>(I::kP) = gt->p_WR;
    x.segment<4>(I::kQ) = math::quat_to_wxyz(gt->q_WR);
  }
  const Eigen::Matrix3d R = math::quat_from_wxyz(x.segment<4>(I::kQ)).toRotationMatrix();
  if (gt_biases) {
    x.segment<3>(I::kAb) = *gt->accel_bias;
    x.segment<3>(I::kWb) = *gt->gyro_bias;
  } else if (s.standstill) {
    x.segment<3>(I::kWb) = mean_w;
  }
  // Gravity from the mean specific force in W: the accelerometer measures f = Rᵀ(a − g) + a_b, so over the window
  // g = ā − mean(R_k (f_k − a_b)). Each sample is rotated into W by the gyro integrated over the window (midpoint
  // rule, backwards from the attitude at t), so rotation during the window does not tilt the estimate. The mean
  // acceleration ā is zero at standstill; in motion it comes from the ground-truth velocities at both ends of the
  // window when there are any, and is otherwise unknown (zero with the large `gravity_std_motion`).
  const Eigen::Vector3d a_b = x.segment<3>(I::kAb), w_b = x.segment<3>(I::kWb);
  std::vector<Eigen::Matrix3d> R_t_k(static_cast<std::size_t>(n));  // R_{R(t) R(t_k)}
  R_t_k.back() = Eigen::Matrix3d::Identity();
  for (int k = n - 2; k >= 0; --k) {
    const double dt = to_seconds(in[static_cast<std::size_t>(k + 1)]->t - in[static_cast<std::size_t>(k)]->t);
    const Eigen::Vector3d w =
        0.5 * (in[static_cast<std::size_t>(k)]->m.gyro + in[static_cast<std::size_t>(k + 1)]->m.gyro) - w_b;
    R_t_k[static_cast<std::size_t>(k)] =
        R_t_k[static_cast<std::size_t>(k + 1)] * math::exp_so3(w * dt).toRotationMatrix().transpose();
  }
  Eigen::Vector3d f_W = Eigen::Vector3d::Zero();
  for (int k = 0; k < n; ++k) f_W += R * R_t_k[static_cast<std::size_t>(k)] * (in[static_cast<std::size_t>(k)]->m.accel - a_b);
  f_W /= n;
  Eigen::Vector3d a_mean = Eigen::Vector3d::Zero();
  const bool known_motion = !s.standstill && gt && gt_start && gt->v_WR && gt_start->v_WR && gt->t > gt_start->t;
  if (known_motion) a_mean = (*gt->v_WR - *gt_start->v_WR) / to_seconds(gt->t - gt_start->t);
  x.segment<3>(I::kG) = a_mean - f_W;
  double v_std = o.velocity_std_motion;
  if (s.standstill) {
    v_std = o.velocity_std_standstill;
  } else if (gt && gt->v_WR) {
    x.segment<3>(I::kV) = *gt->v_WR;
    v_std = o.velocity_std_groundtruth;
  }
  auto& P = s.P;
  P.block<3, 3>(I::kDv, I::kDv) = v_std * v_std * Eigen::Matrix3d::Identity();
  P.block<3, 3>(I::kDab, I::kDab) = o.accel_bias_std * o.accel_bias_std * Eigen::Matrix3d::Identity();
  const double wb_std = s.standstill && !gt_biases ? std::max(1e-3, s.gyro_std / std::sqrt(static_cast<double>(n)))
                                                   : o.gyro_bias_std;
  P.block<3, 3>(I::kDwb, I::kDwb) = wb_std * wb_std * Eigen::Matrix3d::Identity();
  // g = ā − mean(R_k (f_k − a_b)): its error is the accelerometer bias error rotated into W (correlated with a_b)
  // plus the spread of the mean (standstill, or motion with ground-truth velocities) or the unknown mean
  // acceleration (motion).
  const double g_std = s.standstill || known_motion ? o.gravity_std_standstill : o.gravity_std_motion;
  P.block<3, 3>(I::kDg, I::kDg) =
      g_std * g_std * Eigen::Matrix3d::Identity() + o.accel_bias_std * o.accel_bias_std * Eigen::Matrix3d::Identity();
  P.block<3, 3>(I::kDg, I::kDab) = o.accel_bias_std * o.accel_bias_std * R;  // ∂g/∂a_b = R (at t)
  P.block<3, 3>(I::kDab, I::kDg) = P.block<3, 3>(I::kDg, I::kDab).transpose();
  return s;
}

}  // namespace rtslam::pipeline
