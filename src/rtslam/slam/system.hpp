#pragma once
// The System runs the frame loop through the interfaces only: advance the robots to the datum's time, hand the
// datum to its sensor's DataManager, then let the MapManager keep the map clean.
#include <memory>

#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/map.hpp"

namespace rtslam::slam {

class System {
 public:
  System(World& world, Map& map, std::unique_ptr<MapManager> map_manager);
  /// Processes one sensor datum (time-ordered). Returns the frame statistics; throws DataError if time goes
  /// backwards or the sensor is unknown.
  FrameStats process(const RawData& raw);
  long frames() const { return frame_; }
  Map& map() { return map_; }

 private:
  World& world_;
  Map& map_;
  std::unique_ptr<MapManager> map_manager_;
  long frame_ = 0;
};

}  // namespace rtslam::slam
