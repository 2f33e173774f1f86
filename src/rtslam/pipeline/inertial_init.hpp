#pragma once
// Options of the inertial robot of the image pipeline (issue "Inertial/visual SLAM"; MATH.md "Robots", inertial): the
// `imu:` section of a configuration (the start's keys, strategies/inertial_start.hpp and vi_init.hpp, and the noise
// model, saturation, time offset, extrinsics and calibration check) and the model's noise parameters from a
// calibration.
#include <optional>
#include <string>

#include <yaml-cpp/yaml.h>

#include "rtslam/calib/check.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/calibration.hpp"
#include "rtslam/models/robots/inertial.hpp"
#include "rtslam/strategies/inertial_start.hpp"
#include "rtslam/strategies/vi_init.hpp"

namespace rtslam::pipeline {

/// imu/vi_init: {enabled, window, min_frames, cells_x, cells_y, patch_size, min_score, search_px, min_features,
/// standstill_max_disparity_px, min_parallax_px, max_reprojection_px, gravity, max_speed}.
void read_vi_init(YamlMap section, strategies::ViInitOptions& o);
YAML::Node vi_init_to_yaml(const strategies::ViInitOptions& o);

/// The start's options (strategies::InertialStartOptions) and the rest of the `imu:` section.
struct InertialOptions : strategies::InertialStartOptions {
  // The noise model: the calibration's densities (sensor.yaml / imu.yaml), each replaced by its key when given,
  // then multiplied by the scales.
  std::optional<double> accelerometer_noise_density;  // m/s²/√Hz
  std::optional<double> gyroscope_noise_density;      // rad/s/√Hz
  std::optional<double> accelerometer_random_walk;    // m/s³/√Hz
  std::optional<double> gyroscope_random_walk;        // rad/s²/√Hz
  double noise_scale = 1.0;               // multiplies the calibration's white-noise densities (vibration)
  double random_walk_scale = 1.0;         // multiplies the calibration's bias random walks
  std::optional<double> time_offset_s;    // t_imu = t_cam + t_d; default: the calibration's
  std::optional<double> gyro_saturation;  // rad/s per axis; default: the calibration's (none if unknown)
  std::optional<double> accel_saturation; // m/s² per axis; default: the calibration's
  bool estimate_extrinsics = false;       // camera–IMU T_RS as a map block, from the calibration with the prior:
  double extrinsics_std_m = 0.02;         //   position std (m, per axis) ...
  double extrinsics_std_deg = 1.0;        //   ... and rotation std (deg, per axis)
  strategies::ViInitOptions vi_init;                  // the visual-inertial start (vi_init.hpp); disabled: IMU-only start
  calib::CheckOptions calibration_check;  // `rtslam run`'s check of T_RS and t_d against the data (calib/check.hpp)
  void validate() const;
};

/// imu: {init, init_window, standstill_max_gyro_std, ...} (keys as the fields, init_window in s).
void read_inertial(YamlMap section, InertialOptions& o);
YAML::Node inertial_to_yaml(const InertialOptions& o);

/// The model's noise densities from a calibration and the option scales (ConfigError if the calibration is absent).
models::InertialParams inertial_params(const std::optional<io::ImuCalibration>& imu, const InertialOptions& o,
                                       const std::string& dataset);

}  // namespace rtslam::pipeline
