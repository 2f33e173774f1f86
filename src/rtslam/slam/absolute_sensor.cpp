#include "rtslam/slam/absolute_sensor.hpp"

#include <utility>

namespace rtslam::slam {

AbsoluteSensor::AbsoluteSensor(std::string name, Kind kind, math::Pose T_RS)
    : Sensor(std::move(name), T_RS), kind_(kind) {}

}  // namespace rtslam::slam
