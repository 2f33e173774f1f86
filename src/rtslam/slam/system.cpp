#include "rtslam/slam/system.hpp"

#include <chrono>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"

namespace rtslam::slam {

System::System(World& world, Map& map, std::unique_ptr<MapManager> map_manager)
    : world_(world), map_(map), map_manager_(std::move(map_manager)) {
  RTSLAM_CHECK(map_manager_ != nullptr, "a System needs a MapManager");
}

FrameStats System::process(const RawData& raw) {
  const auto t0 = std::chrono::steady_clock::now();
  Sensor* sensor = nullptr;
  for (const auto& r : map_.robots())  // (not Map::sensors(): its list would be allocated every frame)
    for (const auto& s : r->sensors())
      if (s->id() == raw.sensor_id) sensor = s.get();
  if (!sensor) throw DataError(fmt::format("datum at t = {} ns names unknown sensor {}", raw.t, raw.sensor_id));
  if (!sensor->data_manager()) throw ConfigError(fmt::format("sensor '{}' has no data manager", sensor->name()));
  FrameStats stats;
  stats.t = raw.t;
  // Every robot of the map moves to the datum's time (robots share the map's covariance).
  for (const auto& r : map_.robots()) {
    if (!r->predict_to(raw.t)) {
      throw DataError(fmt::format("datum at t = {} ns is older than robot '{}' (t = {} ns): timestamps go backwards",
                                  raw.t, r->name(), r->time()));
    }
  }
  const auto t1 = std::chrono::steady_clock::now();
  stats.time_predict_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  sensor->data_manager()->process(map_, *sensor, raw, frame_, stats);
  const auto t2 = std::chrono::steady_clock::now();
  map_manager_->manage(map_, *sensor, frame_, stats);
  const auto t3 = std::chrono::steady_clock::now();
  stats.time_map_ms = std::chrono::duration<double, std::milli>(t3 - t2).count();
  stats.time_total_ms = std::chrono::duration<double, std::milli>(t3 - t0).count();
  stats.landmarks_in_map = static_cast<int>(map_.landmarks().size());
  ++frame_;
  return stats;
}

}  // namespace rtslam::slam
