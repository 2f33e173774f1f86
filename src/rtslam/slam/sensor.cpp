#include "rtslam/slam/sensor.hpp"

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/robot.hpp"

namespace rtslam::slam {

Sensor::Sensor(std::string name, math::Pose T_RS) : name_(std::move(name)), T_RS_(T_RS) {}
Sensor::~Sensor() = default;

void Sensor::attach(Robot& robot, int id) {
  robot_ = &robot;
  id_ = id;
  if (extrinsics_prior_ && block_ == filter::kNoBlock && robot.in_map()) {
    Eigen::Matrix<double, 7, 1> x;
    x << T_RS_.p, math::quat_to_wxyz(T_RS_.q);
    // A pose in the robot frame does not move with the world: its rows of the unobservable basis are zero.
    const auto b = robot.map().state().add_block(extrinsics_layout(), x, *extrinsics_prior_);
    if (!b) throw ConfigError(fmt::format("sensor '{}': the map has no room for its extrinsics", name_));
    block_ = *b;
  }
}

filter::BlockLayout Sensor::extrinsics_layout() { return filter::BlockLayout::euclidean(3).then_quaternion(); }

void Sensor::estimate_extrinsics(const Eigen::Matrix<double, 6, 6>& prior_cov) {
  RTSLAM_CHECK(block_ == filter::kNoBlock && (robot_ == nullptr || !robot_->in_map()),
               fmt::format("sensor '{}': extrinsics estimation must be requested before the robot joins a map", name_));
  extrinsics_prior_ = prior_cov;
}

math::Pose Sensor::T_RS(const Eigen::VectorXd& mean) const {
  if (block_ == filter::kNoBlock) return T_RS_;
  const int a = robot_->map().state().block(block_).ambient_offset;
  return {math::quat_from_wxyz(mean.segment<4>(a + 3)), mean.segment<3>(a)};
}

void Sensor::set_data_manager(std::unique_ptr<DataManager> dm) { data_manager_ = std::move(dm); }

math::Pose Sensor::pose_in_world(const Eigen::VectorXd& mean, Eigen::Matrix<double, 6, 6>* J_TWS_TWR,
                                 Eigen::Matrix<double, 6, 6>* J_TWS_TRS) const {
  return math::compose_poses(robot_->pose(mean), T_RS(mean), J_TWS_TWR,
                             block_ == filter::kNoBlock ? nullptr : J_TWS_TRS);
}

PinholeSensor::PinholeSensor(std::string name, const models::CameraIntrinsics& intrinsics, math::Pose T_RS)
    : Sensor(std::move(name), T_RS), camera_(intrinsics) {}

bool PinholeSensor::project(const Eigen::Vector3d& h_S, Eigen::Vector2d& z, Eigen::Matrix<double, 2, 3>* J_z_h) const {
  return camera_.project(h_S, z, J_z_h);
}

bool PinholeSensor::in_field(const Eigen::Vector2d& z, double margin) const { return camera_.in_image(z, margin); }

bool PinholeSensor::back_project(const Eigen::Vector2d& z, Eigen::Vector3d& ray_S,
                                 Eigen::Matrix<double, 3, 2>* J_ray_z) const {
  return camera_.unproject(z, ray_S, J_ray_z);
}

}  // namespace rtslam::slam
