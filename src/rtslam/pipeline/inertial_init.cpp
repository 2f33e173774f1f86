#include "rtslam/pipeline/inertial_init.hpp"

#include <cmath>
#include <tuple>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/io/source.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::pipeline {

void InertialOptions::validate() const {
  const std::string w = "imu";
  InertialStartOptions::validate();
  // Scales and extrinsics priors: positive, and below values no IMU could mean (a unit slip otherwise).
  for (const auto& [key, v, hi, unit] :
       {std::tuple{"noise_scale", noise_scale, 1000.0, ""}, std::tuple{"random_walk_scale", random_walk_scale, 1000.0, ""},
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

void read_vi_init(YamlMap m, strategies::ViInitOptions& o) {
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

YAML::Node vi_init_to_yaml(const strategies::ViInitOptions& o) {
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

}  // namespace rtslam::pipeline
