#pragma once
// Online estimation of a camera's clock offset (config `camera/time_offset`; Sensor::estimate_time_offset): each
// camera gets a 1-row block δt_d, the residual of t_d around the offset the images were stamped with (imu/time_offset
// or the calibration's), with a zero-mean prior of std sigma_ms; the robot is predicted to the stamp plus the
// current estimate clamped to ±max_ms (slam/sensor.hpp has the measurement model).
#include <yaml-cpp/yaml.h>

#include "rtslam/core/yaml.hpp"
#include "rtslam/slam/fwd.hpp"

namespace rtslam::slam {

struct TimeOffsetOptions {
  bool estimate = false;  // off by default (docs/configuration.md: the measurements behind it)
  double sigma_ms = 5.0;  // ms, prior std of δt_d
  double max_ms = 50.0;   // ms, the largest shift the robot is predicted with (the estimate is clamped to it)
  void validate() const;
};

void read_time_offset(YamlMap section, TimeOffsetOptions& o);
YAML::Node time_offset_to_yaml(const TimeOffsetOptions& o);

/// Requests the estimation on `sensor` when `o.estimate` (before its robot joins a map).
void apply_time_offset(Sensor& sensor, const TimeOffsetOptions& o);

}  // namespace rtslam::slam
