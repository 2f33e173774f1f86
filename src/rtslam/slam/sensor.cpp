#include "rtslam/slam/sensor.hpp"

#include "rtslam/core/error.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/robot.hpp"

namespace rtslam::slam {

Sensor::Sensor(std::string name, math::Pose T_RS) : name_(std::move(name)), T_RS_(T_RS) {}
Sensor::~Sensor() = default;

void Sensor::attach(Robot& robot, int id) {
  robot_ = &robot;
  id_ = id;
}

void Sensor::set_data_manager(std::unique_ptr<DataManager> dm) { data_manager_ = std::move(dm); }

math::Pose Sensor::pose_in_world(const Eigen::VectorXd& mean, Eigen::Matrix<double, 6, 6>* J_TWS_TWR) const {
  return math::compose_poses(robot_->pose(mean), T_RS_, J_TWS_TWR, nullptr);
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
