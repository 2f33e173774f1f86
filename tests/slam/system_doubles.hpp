#pragma once
// Stand-ins for the System's strategies, shared by the slam tests: a datum type, a data manager that records what
// it is given, and a map manager that does nothing.
#include <string>
#include <vector>

#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/sensor.hpp"

namespace rtslam::slam {

struct Blob final : RawData {
  int value = 0;
  bool released = false;
  void release() override { released = true; }
};

class CountingDataManager final : public DataManager {
 public:
  void process(Map&, Sensor&, const RawData& raw, long frame, FrameStats& stats) override {
    times.push_back(raw.t);
    frames.push_back(frame);
    stats.updated = updated;
  }
  std::string name() const override { return "counting"; }
  std::vector<TimeNs> times;
  std::vector<long> frames;
  int updated = 10;
};

class NoMapManager final : public MapManager {
 public:
  bool has_room(const Map&, int) const override { return true; }
  void manage(Map&, const Sensor&, long, FrameStats&) override {}
};

}  // namespace rtslam::slam
