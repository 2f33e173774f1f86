#include "rtslam/sim/imu.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"

namespace rtslam::sim {

using Eigen::Vector3d;

void ImuSynthOptions::read(YamlMap& m) {
  m.get("rate_hz", rate_hz);
  m.get("gyroscope_noise_density", noise.gyro_noise_density);
  m.get("gyroscope_random_walk", noise.gyro_random_walk);
  m.get("accelerometer_noise_density", noise.accel_noise_density);
  m.get("accelerometer_random_walk", noise.accel_random_walk);
  m.get("noise", noise_enabled);
  m.get("gravity", gravity);
  m.get("initial_gyro_bias_std", initial_gyro_bias_std);
  m.get("initial_accel_bias_std", initial_accel_bias_std);
  m.get("gyro_saturation_deg_s", gyro_saturation_deg_s);
  m.get("accel_saturation", accel_saturation);
}

void ImuSynthOptions::validate(const std::string& where) const {
  require_bound(rate_hz > 0.0 && rate_hz <= 10000.0, where, "rate_hz", rate_hz, "in (0, 10000]");
  require_bound(noise.gyro_noise_density >= 0.0, where, "gyroscope_noise_density", noise.gyro_noise_density, ">= 0");
  require_bound(noise.gyro_random_walk >= 0.0, where, "gyroscope_random_walk", noise.gyro_random_walk, ">= 0");
  require_bound(noise.accel_noise_density >= 0.0, where, "accelerometer_noise_density", noise.accel_noise_density,
                ">= 0");
  require_bound(noise.accel_random_walk >= 0.0, where, "accelerometer_random_walk", noise.accel_random_walk, ">= 0");
  require_bound(gravity >= 0.0 && gravity < 100.0, where, "gravity", gravity, "in [0, 100)");
  require_bound(initial_gyro_bias_std >= 0.0, where, "initial_gyro_bias_std", initial_gyro_bias_std, ">= 0");
  require_bound(initial_accel_bias_std >= 0.0, where, "initial_accel_bias_std", initial_accel_bias_std, ">= 0");
  require_bound(gyro_saturation_deg_s >= 0.0, where, "gyro_saturation_deg_s", gyro_saturation_deg_s, ">= 0 (0 = off)");
  require_bound(accel_saturation >= 0.0, where, "accel_saturation", accel_saturation, ">= 0 (0 = off)");
}

void ideal_imu(const KinematicState& s, double gravity, Vector3d& gyro, Vector3d& accel) {
  gyro = s.w_R;
  accel = s.q_WR.conjugate() * (s.a_WR - Vector3d(0.0, 0.0, -gravity));
}

ImuSynthesizer::ImuSynthesizer(const ContinuousTrajectory& trajectory, const ImuSynthOptions& options, Rng rng)
    : traj_(trajectory), opt_(options), rng_(std::move(rng)) {
  opt_.validate("imu");
  b_g_ = randn_vec<3>(rng_, opt_.initial_gyro_bias_std);
  b_a_ = randn_vec<3>(rng_, opt_.initial_accel_bias_std);
}

SynthImuSample ImuSynthesizer::sample(TimeNs t) {
  if (last_t_ && t < *last_t_)
    throw DataError(fmt::format("imu synthesis: time went backwards ({} ns after {} ns)", t, *last_t_));
  const double dt = last_t_ ? to_seconds(t - *last_t_) : 0.0;
  last_t_ = t;
  if (opt_.noise_enabled && dt > 0.0) {
    b_g_ += randn_vec<3>(rng_, opt_.noise.gyro_random_walk * std::sqrt(dt));
    b_a_ += randn_vec<3>(rng_, opt_.noise.accel_random_walk * std::sqrt(dt));
  }
  SynthImuSample out;
  out.t = t;
  ideal_imu(traj_.at(t), opt_.gravity, out.gyro, out.accel);
  out.gyro_bias = b_g_;
  out.accel_bias = b_a_;
  out.gyro += b_g_;
  out.accel += b_a_;
  if (opt_.noise_enabled) {
    const double sqrt_rate = std::sqrt(opt_.rate_hz);
    out.gyro += randn_vec<3>(rng_, opt_.noise.gyro_noise_density * sqrt_rate);
    out.accel += randn_vec<3>(rng_, opt_.noise.accel_noise_density * sqrt_rate);
  }
  if (opt_.gyro_saturation_deg_s > 0.0) {
    const double lim = opt_.gyro_saturation_deg_s * std::numbers::pi / 180.0;
    out.gyro = out.gyro.cwiseMax(-lim).cwiseMin(lim);
  }
  if (opt_.accel_saturation > 0.0) out.accel = out.accel.cwiseMax(-opt_.accel_saturation).cwiseMin(opt_.accel_saturation);
  return out;
}

}  // namespace rtslam::sim
