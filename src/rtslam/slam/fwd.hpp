#pragma once
// Forward declarations of the object model (World → Maps → Robots and Landmarks; Robots own Sensors; one
// Observation per sensor–landmark pair).
namespace rtslam::slam {
class World;
class Map;
class Robot;
class Sensor;
class Landmark;
struct Observation;
class DataManager;
class MapManager;
class System;
struct RawData;
struct HealthOptions;
}  // namespace rtslam::slam
