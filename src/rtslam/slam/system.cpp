#include "rtslam/slam/system.hpp"

#include <algorithm>
#include <chrono>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/slam/sensor.hpp"

namespace rtslam::slam {

System::System(Map& map, std::unique_ptr<MapManager> map_manager, SystemOptions options)
    : map_(map), map_manager_(std::move(map_manager)), options_(options),
      pending_(options.max_pending + 1) {
  RTSLAM_CHECK(map_manager_ != nullptr, "a System needs a MapManager");
  options_.health.validate();
  if (options_.max_pending < 1) throw ConfigError("System: max_pending must be >= 1");
}

int System::add_robot(std::unique_ptr<Robot> robot, std::unique_ptr<RobotStarter> starter) {
  RTSLAM_CHECK(robot != nullptr && starter != nullptr, "System::add_robot: null robot or starter");
  RTSLAM_CHECK(!robot->in_map(), "System::add_robot: the robot is already in a map");
  robot->assign_sensor_ids(map_);
  Slot& slot = slots_.emplace_back(options_);
  slot.robot = robot.get();
  slot.waiting = std::move(robot);
  slot.starter = std::move(starter);
  slot.input_id = map_.take_sensor_id();
  // Spares for the window and the pending queue: warm-up allocations, not per-datum ones.
  spares_.reserve(spares_.size() + options_.max_pending + 64);
  return slot.input_id;
}

System::Slot* System::slot_of_sensor(int sensor_id, const Sensor** sensor) {
  for (Slot& s : slots_) {
    for (const auto& c : s.robot->sensors()) {
      if (c->id() == sensor_id) {
        *sensor = c.get();
        return &s;
      }
    }
  }
  return nullptr;
}

TimeNs System::filter_time(const RawData& datum, const Sensor& sensor) const {
  return sensor.robot().in_map() ? datum.t + sensor.time_shift(map_.state().mean_vector()) : datum.t;
}

bool System::covered(const RawData& datum) {
  const Sensor* sensor = nullptr;
  const TimeNs t = slot_of_sensor(datum.sensor_id, &sensor) != nullptr ? filter_time(datum, *sensor) : datum.t;
  for (const Slot& s : slots_) {
    if (s.robot->needs_inputs() && (!s.last_input_t || *s.last_input_t < t)) return false;
  }
  return true;
}

void System::recycle(std::unique_ptr<RawData> datum) {
  datum->release();
  spares_.push_back(std::move(datum));
}

void System::feed(std::unique_ptr<RawData> datum) {
  RTSLAM_CHECK(datum != nullptr, "System::feed: null datum");
  for (Slot& s : slots_) {
    if (datum->sensor_id != s.input_id) continue;
    if (s.last_input_t && datum->t <= *s.last_input_t) {
      throw DataError(fmt::format("input of robot '{}' at t = {} ns is not after the previous one (t = {} ns)",
                                  s.robot->name(), datum->t, *s.last_input_t));
    }
    const auto* imu = dynamic_cast<const ImuData*>(datum.get());
    if (imu != nullptr) {
      if (s.recent.size() + 1 >= s.recent.capacity()) s.recent.pop_front();
      s.recent.push_back(*imu);
    }
    if (s.robot->in_map()) s.robot->add_input(*datum);
    s.last_input_t = datum->t;
    if (imu == nullptr && !s.robot->in_map()) {
      // Inputs of another type (odometry increments) are not in the window: the latest one is kept for the start.
      if (s.latest_input) recycle(std::move(s.latest_input));
      s.latest_input = std::move(datum);
    } else {
      recycle(std::move(datum));
    }
    // At equal timestamps the input comes first: data up to its time are covered now.
    while (!pending_.empty() && covered(*pending_.front())) {
      std::unique_ptr<RawData> d = std::move(pending_.front());
      pending_.pop_front();
      handle(*d);
      recycle(std::move(d));
    }
    return;
  }
  const Sensor* sensor = nullptr;
  if (slot_of_sensor(datum->sensor_id, &sensor) == nullptr) {
    throw DataError(fmt::format("datum at t = {} ns names unknown sensor {}", datum->t, datum->sensor_id));
  }
  if (pending_.empty() && covered(*datum)) {
    handle(*datum);
    recycle(std::move(datum));
    return;
  }
  if (pending_.size() >= options_.max_pending) {
    throw DataError(fmt::format("{} data wait for proprioceptive inputs (the IMU stream stops or lags behind the "
                                "camera; last datum at t = {} ns)",
                                pending_.size(), datum->t));
  }
  pending_.push_back(std::move(datum));
}

void System::handle(const RawData& datum) {
  if (finished()) return;
  const Sensor* sensor = nullptr;
  Slot* slot = slot_of_sensor(datum.sensor_id, &sensor);
  if (slot == nullptr) {
    throw DataError(fmt::format("datum at t = {} ns names unknown sensor {}", datum.t, datum.sensor_id));
  }
  if (slot->counts.started && !slot->restarting) {
    step(*slot, *sensor, datum);
    return;
  }
  // A robot starts from the data of its landmark sensors; an absolute fix before the start has nothing to correct.
  if (!sensor->observes_landmarks()) return;
  const std::optional<RobotStart> s = slot->starter->offer(datum, slot->recent);
  if (!s) return;
  start(*slot, *s, *sensor);
  for (const RawData* d : s->replay) {
    if (finished()) break;
    step(*slot, *sensor, *d);
  }
}

void System::start(Slot& slot, const RobotStart& s, const Sensor& sensor) {
  const bool first = !slot.counts.started;
  if (first) {
    map_.add_robot(std::move(slot.waiting), s.x, s.P, s.t);  // (a time offset's block starts at 0 residual)
    for (std::size_t k = 0; k < slot.recent.size(); ++k) slot.robot->add_input(slot.recent[k]);
    if (slot.latest_input) {
      slot.robot->add_input(*slot.latest_input);
      recycle(std::move(slot.latest_input));
    }
  } else {
    // The start is at the time of the sensor's datum: in the robot's clock, shifted by the current time offset.
    const TimeNs t = std::max(s.t + sensor.time_shift(map_.state().mean_vector()), slot.robot->time());
    slot.robot->reset(slot.robot->reanchor(s.x, slot.last_good_x, options_.health), s.P, t);
  }
  slot.counts.started = true;
  slot.counts.start = s.description;
  slot.restarting = false;
  slot.monitor.restart(s.t);
  slot.last_good_x = map_.state().mean(slot.robot->block());
  slot.starter->started(map_, *slot.robot, first);
  for (Observer* o : observers_) o->on_start(*slot.robot, s);
}

void System::step(Slot& slot, const Sensor& sensor, const RawData& datum) {
  const long index = frame_;
  FrameStats stats = process(datum);
  Robot& robot = *slot.robot;
  for (const auto& h : hooks_) h->after_step(map_, robot, sensor, datum, slot.recent, stats);
  const HealthMonitor::Verdict verdict = slot.monitor.check(map_, robot, stats);
  stats.health = static_cast<int>(verdict.health);
  if (!verdict.note.empty()) logger("slam")->warn("t = {:.3f} s: {}", to_seconds(datum.t), verdict.note);
  slot.counts.final_health = verdict.health;
  if (verdict.health == Health::Ok) {
    if (stats.updated >= options_.health.min_updated && !slot.monitor.suspect()) {
      slot.last_good_x = map_.state().mean(robot.block());
    }
  } else {
    ++(verdict.health == Health::Lost ? slot.counts.frames_lost : slot.counts.frames_diverged);
    logger("slam")->warn("t = {:.3f} s: tracking {}: {}{}", to_seconds(datum.t), to_string(verdict.health),
                         verdict.reason, options_.health.reset ? "; re-initializing" : "");
    if (options_.health.reset) {
      while (!map_.landmarks().empty()) map_.remove_landmark(*map_.landmarks().back());
      stats.reset = true;
      ++slot.counts.resets;
      slot.restarting = true;  // the next data go to the starter
      slot.starter->restart();
    }
  }
  const StepReport report{index, datum, map_, robot, sensor, stats, verdict.reason};
  for (Observer* o : observers_) o->on_step(report);
}

FrameStats System::process(const RawData& raw) {
  const auto t0 = std::chrono::steady_clock::now();
  const Sensor* found = nullptr;
  for (const auto& r : map_.robots())  // (not Map::sensors(): its list would be allocated every frame)
    for (const auto& s : r->sensors())
      if (s->id() == raw.sensor_id) found = s.get();
  if (!found) throw DataError(fmt::format("datum at t = {} ns names unknown sensor {}", raw.t, raw.sensor_id));
  Sensor& sensor = const_cast<Sensor&>(*found);
  if (!sensor.data_manager()) throw ConfigError(fmt::format("sensor '{}' has no data manager", sensor.name()));
  FrameStats stats;
  stats.t = raw.t;
  stats.sensor_id = raw.sensor_id;
  stats.landmark_frame = sensor.observes_landmarks();
  if (stats.landmark_frame && (map_frame_ < 0 || raw.t != map_frame_t_ || &sensor.robot() != map_frame_robot_)) {
    ++map_frame_;
    map_frame_t_ = raw.t;
    map_frame_robot_ = &sensor.robot();
  }
  stats.frame = std::max(map_frame_, 0L);
  // Every robot of the map moves to the datum's time in the robots' clock: its stamp shifted by the sensor's current
  // time offset estimate (robots share the map's covariance). A shift that would take the sensor's robot back in
  // time (the estimate decreased, or another camera of the same time was processed with a larger one) is raised to
  // the robot's time, and one beyond the inputs (a start's replayed data were covered at the shift of their time) is
  // cut there: the sensor's pose model moves the robot by the rest (Sensor::pose_in_world).
  TimeNs t = raw.t;
  if (sensor.time_block() != filter::kNoBlock) {
    t = raw.t + sensor.time_shift(map_.state().mean_vector());
    for (const Slot& s : slots_) {
      if (s.robot->in_map() && s.robot->needs_inputs() && s.last_input_t) t = std::min(t, std::max(raw.t, *s.last_input_t));
    }
    if (t < sensor.robot().time() && raw.t + sensor.max_time_shift() >= sensor.robot().time()) t = sensor.robot().time();
    sensor.set_applied_time_shift(t - raw.t);
  }
  for (const auto& r : map_.robots()) {
    if (!r->predict_to(t)) {
      throw DataError(fmt::format("datum at t = {} ns is older than robot '{}' (t = {} ns): timestamps go backwards",
                                  raw.t, r->name(), r->time()));
    }
  }
  const auto t1 = std::chrono::steady_clock::now();
  stats.time_predict_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  sensor.data_manager()->process(map_, sensor, raw, stats.frame, stats);
  const auto t2 = std::chrono::steady_clock::now();
  if (stats.landmark_frame) map_manager_->manage(map_, sensor, stats.frame, stats);
  const auto t3 = std::chrono::steady_clock::now();
  stats.time_map_ms = std::chrono::duration<double, std::milli>(t3 - t2).count();
  stats.time_total_ms = std::chrono::duration<double, std::milli>(t3 - t0).count();
  stats.landmarks_in_map = static_cast<int>(map_.landmarks().size());
  if (stats.landmark_frame) ++frame_;  // frames count the landmark sensors' data (absolute fixes come in between)
  return stats;
}

}  // namespace rtslam::slam
