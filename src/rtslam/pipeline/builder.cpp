#include "rtslam/pipeline/builder.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/pipeline/starters.hpp"
#include "rtslam/slam/absolute_sensor.hpp"
#include "rtslam/slam/odometry_robot.hpp"
#include "rtslam/slam/time_offset.hpp"
#include "rtslam/strategies/absolute.hpp"
#include "rtslam/strategies/active_search.hpp"
#include "rtslam/strategies/known_association.hpp"
#include "rtslam/strategies/map_policies.hpp"
#include "rtslam/strategies/planar_motion.hpp"
#include "rtslam/strategies/zero_velocity.hpp"

namespace rtslam::pipeline {

namespace {

template <class Map>
std::string names_of(const Map& m) {
  std::vector<std::string> n;
  for (const auto& [k, v] : m) n.push_back(k);
  return fmt::format("{}", fmt::join(n, ", "));
}

// The data managers' seed: one per run, derived from slam/seed.
std::uint64_t dm_seed(const ImageSlamOptions& o) { return o.seed * 7919 + 1; }

}  // namespace

Registry Registry::builtin() {
  Registry r;
  r.add_robot(
      "constant_velocity",
      [](const BuildContext& c) -> std::unique_ptr<slam::Robot> {
        return std::make_unique<slam::ConstantVelocityRobot>(c.options.motion);
      },
      [](const BuildContext& c, const BuiltSystem& b) -> std::unique_ptr<slam::RobotStarter> {
        const ImageSlamOptions& o = c.options;
        std::optional<KnownLandmarkSet> known;
        if (!o.known_landmarks.empty()) {
          known = load_known_landmarks(o.known_landmarks, o.known_landmarks_convention);
          const math::Pose& T_RS = b.cameras.front().T_RS;
          if (o.known_landmarks_convention == "scenelib" &&
              (T_RS.p.norm() > 1e-9 || T_RS.q.angularDistance(Eigen::Quaterniond::Identity()) > 1e-9)) {
            throw ConfigError(fmt::format("slam/known_landmarks_convention = scenelib: the camera of '{}' must be the "
                                          "robot (T_RS = identity); use 'robot' when T_RS carries the frame change",
                                          c.dataset));
          }
        }
        return std::make_unique<PoseStarter>(o.initial_velocity_std, std::move(known), c.initial_state,
                                             c.initial_cov);
      });
  r.add_robot(
      "inertial",
      [](const BuildContext& c) -> std::unique_ptr<slam::Robot> {
        if (!c.options.known_landmarks.empty()) {
          throw ConfigError("slam/known_landmarks is not supported with slam/robot = inertial yet");
        }
        return std::make_unique<slam::InertialRobot>(inertial_params(c.rig.imu, c.options.imu, c.dataset));
      },
      [](const BuildContext& c, const BuiltSystem& b) -> std::unique_ptr<slam::RobotStarter> {
        const BuiltCamera& cam = b.cameras.front();
        return std::make_unique<InertialStarter>(
            c.options.imu, *cam.sensor, cam.intrinsics, cam.T_RS,
            dynamic_cast<strategies::ActiveSearchDataManager*>(cam.data_manager));
      });
  r.add_robot(
      "odometry",
      [](const BuildContext& c) -> std::unique_ptr<slam::Robot> {
        if (!c.options.known_landmarks.empty()) {
          throw ConfigError("slam/known_landmarks is not supported with slam/robot = odometry yet");
        }
        // With one camera and no absolute sensor only the odometry tells the scale, and the EKF alone makes it
        // badly (slam::OdometryScaleOptions): the map's scale is kept at the odometry's unless told otherwise.
        const bool scale_from_odometry = c.options.camera_indices().size() == 1 && !c.options.position_sensor.enabled &&
                                         !c.options.pose_sensor.enabled;
        if (c.options.odometry_rescale == "on" &&
            (c.options.position_sensor.enabled || c.options.pose_sensor.enabled)) {
          throw ConfigError(
              "odometry/rescale = on cannot be used with an absolute sensor (position_sensor, "
              "pose_sensor): the sensor gives the map's scale");
        }
        slam::OdometryScaleOptions scale = c.options.odometry_scale;
        scale.enabled =
            c.options.odometry_rescale == "on" || (c.options.odometry_rescale == "auto" && scale_from_odometry);
        if (scale_from_odometry && !scale.enabled) {
          logger("slam")->warn(
              "slam/robot: odometry with one camera and odometry/rescale off: the map's scale, and with it the "
              "trajectory, can come out worse than the odometry alone (docs/configuration.md section odometry)");
        }
        if (c.options.camera_indices().size() == 1 && !c.options.pose_sensor.enabled &&
            !c.options.planar_motion.enabled) {
          logger("slam")->info(
              "slam/robot: odometry with one camera: nothing measures the robot's tilt (no gravity reference); on a "
              "flat floor planar_motion holds it (docs/configuration.md section planar_motion)");
        }
        return std::make_unique<slam::OdometryRobot>(c.options.odometry, "robot", scale);
      },
      [](const BuildContext& c, const BuiltSystem&) -> std::unique_ptr<slam::RobotStarter> {
        // At the first image, at the given pose [p q] (a known start) or the origin with zero covariance (the gauge).
        Eigen::VectorXd x0(7);
        x0 << 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0;
        if (c.initial_state) x0 = *c.initial_state;
        const Eigen::MatrixXd P0 = c.initial_cov.size() > 0 ? c.initial_cov : Eigen::MatrixXd::Zero(6, 6);
        if (x0.size() != 7 || P0.rows() != 6 || P0.cols() != 6) {
          throw ConfigError(fmt::format("the odometry robot of '{}' starts from a pose [p q] (7 entries, covariance "
                                        "6x6), not {} entries",
                                        c.dataset, x0.size()));
        }
        return std::make_unique<PoseStarter>(c.options.initial_velocity_std, std::nullopt, x0, P0);
      });
  r.add_data_manager("active_search", [](const BuildContext& c, const slam::MapManager& mm,
                                         const models::CameraIntrinsics& in,
                                         std::uint64_t seed) -> std::unique_ptr<slam::DataManager> {
    return std::make_unique<strategies::ActiveSearchDataManager>(c.options.search, mm, in.width, in.height, seed);
  });
  r.add_data_manager("known_association", [](const BuildContext& c, const slam::MapManager& mm,
                                             const models::CameraIntrinsics& in,
                                             std::uint64_t seed) -> std::unique_ptr<slam::DataManager> {
    return std::make_unique<strategies::KnownAssociationDataManager>(c.options.association, mm, in.width, in.height,
                                                                     seed);
  });
  r.add_map_manager("policy", [](const BuildContext& c) -> std::unique_ptr<slam::MapManager> {
    return std::make_unique<strategies::PolicyMapManager>(c.options.map);
  });
  return r;
}

void Registry::add_robot(const std::string& name, RobotMaker robot, StarterMaker starter) {
  robots_[name] = RobotEntry{std::move(robot), std::move(starter)};
}
void Registry::add_data_manager(const std::string& name, DataManagerMaker maker) {
  data_managers_[name] = std::move(maker);
}
void Registry::add_map_manager(const std::string& name, MapManagerMaker maker) {
  map_managers_[name] = std::move(maker);
}
std::vector<std::string> Registry::robot_names() const {
  std::vector<std::string> n;
  for (const auto& [k, v] : robots_) n.push_back(k);
  return n;
}

void Registry::check(const ImageSlamOptions& o) const {
  if (!robots_.count(o.robot)) {
    throw ConfigError(fmt::format("slam/robot = '{}' must be one of: {}", o.robot, names_of(robots_)));
  }
  if (!data_managers_.count(o.data_manager)) {
    throw ConfigError(
        fmt::format("slam/data_manager = '{}' must be one of: {}", o.data_manager, names_of(data_managers_)));
  }
  if (!map_managers_.count(o.map_manager)) {
    throw ConfigError(fmt::format("slam/map_manager = '{}' must be one of: {}", o.map_manager, names_of(map_managers_)));
  }
}

BuiltSystem Registry::build(const BuildContext& c) const {
  const ImageSlamOptions& o = c.options;
  o.validate();
  check(o);
  for (const int k : o.camera_indices()) {
    if (k >= static_cast<int>(c.rig.cameras.size())) {
      throw ConfigError(fmt::format("slam/camera{} = {}: dataset '{}' has {} camera(s)", o.cameras.empty() ? "" : "s",
                                    k, c.dataset, c.rig.cameras.size()));
    }
  }
  BuiltSystem b;
  b.world = std::make_unique<slam::World>();
  filter::StateOptions so;
  so.tangent_capacity = o.state_capacity;
  if (o.consistency == "oc") so.nullspace_dim = slam::Robot::kNullspaceDim;
  b.map = &b.world->add_map(so);
  std::unique_ptr<slam::MapManager> mm = map_managers_.at(o.map_manager)(c);
  b.map_manager = mm.get();
  slam::SystemOptions sys;
  sys.health = o.health;
  sys.max_steps = o.max_frames * static_cast<long>(o.camera_indices().size());  // max_frames counts times
  // The starters' IMU window: the longest a start looks back, with room for a 1.5× faster IMU than calibrated.
  const double window_s = 2.0 * o.imu.init_window_s + o.imu.vi_init.max_window_s + 2.0;
  const double rate = c.rig.imu ? std::max(c.rig.imu->rate_hz, 1.0) : 200.0;
  sys.input_window = static_cast<std::size_t>(std::max(64.0, window_s * rate * 1.5));
  b.system = std::make_unique<slam::System>(*b.map, std::move(mm), sys);

  add_robot_to(b, c);
  return b;
}

BuiltRobot Registry::add_robot_to(BuiltSystem& b, const BuildContext& c) const {
  const ImageSlamOptions& o = c.options;
  const bool first = b.robots.empty();
  if (!first) {
    o.validate();
    check(o);
    for (const int k : o.camera_indices()) {
      if (k >= static_cast<int>(c.rig.cameras.size())) {
        throw ConfigError(fmt::format("slam/camera{} = {}: dataset '{}' has {} camera(s)",
                                      o.cameras.empty() ? "" : "s", k, c.dataset, c.rig.cameras.size()));
      }
    }
    // Rows per robot: the map's storage grows by this robot's slam/state_capacity, as the map manager's budget
    // grows by map_manager/map_size with each robot in the map (strategies/map_policies.hpp). The storage is
    // allocated before the run: every robot joins before data are fed (robots enter the map at their start).
    filter::State& state = b.map->state();
    if (state.block_count() > 0) {
      throw ConfigError(fmt::format("robot of '{}': add every robot before feeding data (the map already holds {} "
                                    "state blocks; its storage grows by slam/state_capacity with each robot)",
                                    c.dataset, state.block_count()));
    }
    state.reserve(state.tangent_capacity() + o.state_capacity);
  }
  // Each robot's data managers draw from their own streams (the first robot keeps the single-robot seeds).
  const std::uint64_t robot_seed = dm_seed(o) + 15485863 * static_cast<std::uint64_t>(b.robots.size());
  BuiltSystem view;  // what a starter of a robot after the first sees: that robot and its cameras
  BuiltSystem& target = first ? b : view;
  target.map = b.map;
  target.map_manager = b.map_manager;
  const RobotEntry& entry = robots_.at(o.robot);
  std::unique_ptr<slam::Robot> robot = entry.robot(c);
  // One sensor and data manager per camera; they share the map's landmarks (each landmark has an observation for
  // every sensor: one initialized in a camera is searched in the others).
  const std::vector<int> indices = o.camera_indices();
  for (std::size_t k = 0; k < indices.size(); ++k) {
    const io::CameraCalibration& cal = c.rig.cameras[static_cast<std::size_t>(indices[k])];
    BuiltCamera cam;
    cam.rig_index = indices[k];
    cam.intrinsics = to_intrinsics(cal);
    cam.T_RS = math::Pose::from_isometry(cal.T_RS);
    cam.sensor = &robot->add_sensor(std::make_unique<slam::PinholeSensor>(cal.name, cam.intrinsics, cam.T_RS));
    if (o.robot == "inertial" && o.imu.estimate_extrinsics) {
      Eigen::Matrix<double, 6, 1> var;
      const double rot = o.imu.extrinsics_std_deg * M_PI / 180.0;
      var << Eigen::Vector3d::Constant(o.imu.extrinsics_std_m * o.imu.extrinsics_std_m),
          Eigen::Vector3d::Constant(rot * rot);
      cam.sensor->estimate_extrinsics(var.asDiagonal());
    }
    slam::apply_time_offset(*cam.sensor, o.time_offset);
    // Each camera's data manager draws from its own stream (the first keeps the single-camera seed).
    std::unique_ptr<slam::DataManager> dm =
        data_managers_.at(o.data_manager)(c, *b.map_manager, cam.intrinsics, robot_seed + 104729 * k);
    cam.data_manager = dm.get();
    if (o.consistency == "fej") {
      if (auto* as = dynamic_cast<strategies::ActiveSearchDataManager*>(dm.get())) as->set_first_estimate_jacobians(true);
    }
    cam.sensor->set_data_manager(std::move(dm));
    target.cameras.push_back(cam);
  }
  // Absolute sensors: their own data manager each (strategies/absolute.hpp).
  const bool gravity_aligned = o.robot == "inertial";
  if (o.position_sensor.enabled) {
    target.position_sensor = &robot->add_sensor(std::make_unique<slam::AbsoluteSensor>(
        "position", slam::AbsoluteSensor::Kind::Position, o.position_sensor.T_RS()));
    target.position_sensor->set_data_manager(
        std::make_unique<strategies::AbsoluteDataManager>(o.position_sensor, gravity_aligned));
  }
  if (o.pose_sensor.enabled) {
    target.pose_sensor = &robot->add_sensor(
        std::make_unique<slam::AbsoluteSensor>("pose", slam::AbsoluteSensor::Kind::Pose, o.pose_sensor.T_RS()));
    target.pose_sensor->set_data_manager(std::make_unique<strategies::AbsoluteDataManager>(o.pose_sensor, gravity_aligned));
  }
  if (o.consistency == "fej") robot->set_first_estimate_jacobians(true);
  target.robot = robot.get();
  std::unique_ptr<slam::RobotStarter> starter = entry.starter(c, target);
  target.starter = starter.get();
  if (o.zero_velocity.enabled && robot->rest_rows() <= 0) {  // refused before the System holds the robot
    throw ConfigError(fmt::format("zero_velocity: robot '{}' has no velocity in its state to set to 0; turn "
                                  "zero_velocity off for it",
                                  robot->name()));
  }
  target.input_id = b.system->add_robot(std::move(robot), std::move(starter));
  if (o.planar_motion.enabled) {  // one hook for the system, each robot with its own options
    if (b.planar_motion == nullptr) {
      auto hook = std::make_unique<strategies::PlanarMotionUpdater>();
      b.planar_motion = hook.get();
      b.system->add_hook(std::move(hook));
      b.system->add_observer(*b.planar_motion);  // a restarted robot is told the plane again at the restart's time
    }
    b.planar_motion->add_robot(*target.robot, o.planar_motion);
  }
  if (o.zero_velocity.enabled) {  // likewise
    if (b.zero_velocity == nullptr) {
      auto hook = std::make_unique<strategies::ZeroVelocityUpdater>();
      b.zero_velocity = hook.get();
      b.system->add_hook(std::move(hook));
      b.system->add_observer(*b.zero_velocity);  // it forgets a robot's rest when the robot restarts
    }
    b.zero_velocity->add_robot(*target.robot, o.zero_velocity);
  }
  b.robots.push_back(BuiltRobot{target.robot, target.starter, target.input_id, target.cameras, target.position_sensor,
                              target.pose_sensor});
  return b.robots.back();
}

BuiltSystem build_system(const BuildContext& context) { return Registry::builtin().build(context); }

}  // namespace rtslam::pipeline
