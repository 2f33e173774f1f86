#pragma once
// A small map for the strategy tests: one constant-velocity robot carrying an undistorted 320x240 pinhole camera
// (T_RS = identity, optical axis = robot z), its pose set directly (no motion model), and point landmarks placed
// at chosen pixels by undelayed AHP initialization.
#include <cmath>
#include <memory>

#include <Eigen/Geometry>

#include "rtslam/math/rotation.hpp"
#include "rtslam/models/landmarks/ahp.hpp"
#include "rtslam/slam/landmark_init.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/observation.hpp"
#include "rtslam/slam/robot.hpp"
#include "rtslam/slam/sensor.hpp"
#include "support/test_camera.hpp"

namespace rtslam::strategies::testing {

/// Rotation of the robot about its y axis (the camera's vertical axis) by `yaw_rad`.
inline Eigen::Quaterniond yaw(double yaw_rad) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitY()));
}

struct StrategyRig {
  slam::World world;
  slam::Map* map = nullptr;
  slam::Robot* robot = nullptr;
  slam::Sensor* sensor = nullptr;

  explicit StrategyRig(filter::StateOptions state_options = {}) {
    map = &world.add_map(state_options);
    auto r = std::make_unique<slam::ConstantVelocityRobot>(models::ConstantVelocityParams{});
    sensor = &r->add_sensor(
        std::make_unique<slam::PinholeSensor>("cam", support::qvga_camera(), math::Pose::identity()));
    Eigen::VectorXd x0 = Eigen::VectorXd::Zero(13);
    x0.segment<4>(3) = math::quat_to_wxyz(Eigen::Quaterniond::Identity());
    // Zero covariance: the pose is the gauge, predictions are exact and landmarks uncorrelated with the robot.
    robot = &map->add_robot(std::move(r), x0, Eigen::MatrixXd::Zero(12, 12), 0);
  }

  /// Sets the robot's mean pose (the camera looks along the robot's z axis).
  void set_pose(const Eigen::Vector3d& p_WR, const Eigen::Quaterniond& q_WR) {
    auto x = map->state().mean(robot->block());
    x.head<3>() = p_WR;
    x.segment<4>(3) = math::quat_to_wxyz(q_WR);
  }

  /// A new AHP landmark seen at pixel z from the current pose, at distance `depth_m` along its ray.
  slam::Landmark* place(const Eigen::Vector2d& z, long frame, double depth_m = 2.0) {
    models::AhpPrior prior;
    prior.d_min = 0.5 * depth_m;  // ρ̄ = 1 / (2 d_min) = 1 / depth
    return slam::init_ahp_landmark(*map, *sensor, z, 1.0, prior, frame);
  }

  slam::Observation& obs(slam::Landmark& l) const { return *l.observation_of(*sensor); }

  /// Whether l projects into the image (with `margin_px`) from the current pose; sets obs.h.
  bool visible(slam::Landmark& l, double margin_px = 8.0) const {
    return slam::predict_observation(map->state(), map->state().mean_vector(), obs(l), margin_px, false);
  }
};

}  // namespace rtslam::strategies::testing
