#include "rtslam/slam/time_offset.hpp"

#include "rtslam/slam/sensor.hpp"

namespace rtslam::slam {

void TimeOffsetOptions::validate() const {
  const std::string w = "camera/time_offset";
  require_bound(sigma_ms > 0.0 && sigma_ms <= 100.0, w, "sigma_ms", sigma_ms, "in (0, 100] ms");
  require_bound(max_ms >= 0.0 && max_ms <= 500.0, w, "max_ms", max_ms, "in [0, 500] ms");
}

void read_time_offset(YamlMap m, TimeOffsetOptions& o) {
  m.get("estimate", o.estimate);
  m.get("sigma_ms", o.sigma_ms);
  m.get("max_ms", o.max_ms);
  m.finish();
}

YAML::Node time_offset_to_yaml(const TimeOffsetOptions& o) {
  YAML::Node n;
  n["estimate"] = o.estimate;
  n["sigma_ms"] = o.sigma_ms;
  n["max_ms"] = o.max_ms;
  return n;
}

void apply_time_offset(Sensor& sensor, const TimeOffsetOptions& o) {
  if (!o.estimate) return;
  const double sigma_s = o.sigma_ms * 1e-3;
  sensor.estimate_time_offset(sigma_s * sigma_s, o.max_ms * 1e-3);
}

}  // namespace rtslam::slam
