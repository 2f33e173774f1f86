#pragma once
// The builder: turns a configuration (ImageSlamOptions) and a rig calibration into a slam::System, with the types
// named in the configuration looked up in a Registry. The built-in entries:
//   robots (slam/robot):               constant_velocity (PoseStarter), inertial (InertialStarter),
//                                      odometry (PoseStarter at a pose [p q])
//   data managers (slam/data_manager): active_search (images), known_association (point measurements: the demo)
//   map managers (slam/map_manager):   policy
// A user's own robot, data manager or map manager is one Registry::add_* call away (docs/architecture.md); the
// System built is the only wiring of the object model (the CLI, the points demo, the Python module and the ROS node
// all come through build_system).
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rtslam/io/calibration.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/slam/system.hpp"

namespace rtslam::pipeline {

/// What the parts are made from. `initial_state`: a constant-velocity start other than the origin (the points demo
/// starts at its simulated pose; 13 entries, `initial_cov` 12×12 or empty for the default prior), or the odometry
/// robot's start pose [p q] (7 entries, `initial_cov` 6×6 or empty for zero: a known start).
struct BuildContext {
  const ImageSlamOptions& options;
  const io::Rig& rig;
  std::string dataset;  // for messages
  std::optional<Eigen::VectorXd> initial_state = std::nullopt;
  Eigen::MatrixXd initial_cov = {};
};

/// One camera of the built robot: its sensor and data manager, and its model.
struct BuiltCamera {
  int rig_index = 0;
  slam::Sensor* sensor = nullptr;
  slam::DataManager* data_manager = nullptr;
  models::CameraIntrinsics intrinsics;
  math::Pose T_RS;
};

/// One robot the builder added to a System.
struct BuiltRobot {
  slam::Robot* robot = nullptr;
  slam::RobotStarter* starter = nullptr;
  int input_id = -1;  // the robot's proprioceptive stream (slam::ImuData or slam::OdometryData sensor_id)
  std::vector<BuiltCamera> cameras;
  // Its absolute sensors (position_sensor / pose_sensor enabled), else null.
  slam::Sensor* position_sensor = nullptr;
  slam::Sensor* pose_sensor = nullptr;
};

struct BuiltSystem {
  std::unique_ptr<slam::World> world;
  slam::Map* map = nullptr;
  std::unique_ptr<slam::System> system;
  slam::Robot* robot = nullptr;
  slam::RobotStarter* starter = nullptr;
  int input_id = -1;  // the robot's proprioceptive stream (slam::ImuData::sensor_id)
  std::vector<BuiltCamera> cameras;
  const slam::MapManager* map_manager = nullptr;
  // Absolute sensors (position_sensor / pose_sensor enabled), else null.
  slam::Sensor* position_sensor = nullptr;
  slam::Sensor* pose_sensor = nullptr;
  std::vector<BuiltRobot> robots;  // every robot, in the order added (the first: the fields above)
  strategies::PlanarMotionUpdater* planar_motion = nullptr;  // the system's hook, once a robot has planar_motion
  strategies::ZeroVelocityUpdater* zero_velocity = nullptr;  // idem for zero_velocity
};

class Registry {
 public:
  using RobotMaker = std::function<std::unique_ptr<slam::Robot>(const BuildContext&)>;
  /// Made once the robot has its sensors and their data managers (`built.cameras` filled).
  using StarterMaker = std::function<std::unique_ptr<slam::RobotStarter>(const BuildContext&, const BuiltSystem&)>;
  /// (context, the map manager, the camera, a seed of its own for the camera's random draws).
  using DataManagerMaker = std::function<std::unique_ptr<slam::DataManager>(
      const BuildContext&, const slam::MapManager&, const models::CameraIntrinsics&, std::uint64_t seed)>;
  using MapManagerMaker = std::function<std::unique_ptr<slam::MapManager>(const BuildContext&)>;

  /// The built-in types (header comment).
  static Registry builtin();
  void add_robot(const std::string& name, RobotMaker robot, StarterMaker starter);
  void add_data_manager(const std::string& name, DataManagerMaker maker);
  void add_map_manager(const std::string& name, MapManagerMaker maker);
  std::vector<std::string> robot_names() const;

  /// ConfigError naming the key and the registered names when a type is unknown.
  void check(const ImageSlamOptions& options) const;
  BuiltSystem build(const BuildContext& context) const;
  /// Adds another robot to a built System, in its map: the robot type of context.options (slam/robot, its own
  /// keys), its cameras from context.rig, its start from context.initial_state. Several robots in one world: the
  /// map's landmarks are shared (a landmark one robot's camera initialized is searched and corrected in every
  /// other camera), and every robot is predicted to each datum's time. For a common world frame, give each robot
  /// its start pose in it (a known start: initial_state with zero covariance for the first, the gauge). The map's
  /// rows are per robot: its storage grows by the robot's slam/state_capacity and the policy map manager's budget
  /// is map_manager/map_size per robot in the map. Every robot is added before data are fed (ConfigError after).
  BuiltRobot add_robot_to(BuiltSystem& built, const BuildContext& context) const;

 private:
  struct RobotEntry {
    RobotMaker robot;
    StarterMaker starter;
  };
  std::map<std::string, RobotEntry> robots_;
  std::map<std::string, DataManagerMaker> data_managers_;
  std::map<std::string, MapManagerMaker> map_managers_;
};

/// Registry::builtin().build(context).
BuiltSystem build_system(const BuildContext& context);

}  // namespace rtslam::pipeline
