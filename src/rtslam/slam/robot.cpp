#include "rtslam/slam/robot.hpp"

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/sensor.hpp"

namespace rtslam::slam {

Robot::~Robot() = default;

math::Pose Robot::pose(const Eigen::VectorXd& mean) const {
  const int a = map_->state().block(block_).ambient_offset;
  return {math::quat_from_wxyz(mean.segment<4>(a + 3)), mean.segment<3>(a)};
}

math::Pose Robot::pose() const { return pose(map_->state().mean_vector()); }

Sensor& Robot::add_sensor(std::unique_ptr<Sensor> sensor) {
  RTSLAM_CHECK(sensor != nullptr, "null sensor");
  sensors_.push_back(std::move(sensor));
  Sensor& s = *sensors_.back();
  s.attach(*this, map_ ? map_->take_sensor_id() : -1);
  return s;
}

void Robot::attach(Map& map, int id, const Eigen::VectorXd& mean, const Eigen::MatrixXd& cov, TimeNs t0) {
  RTSLAM_CHECK(map_ == nullptr, "robot already attached to a map");
  const auto block = map.state().add_block(layout(), mean, cov);
  if (!block) throw ConfigError(fmt::format("robot '{}': the map has no room for its state", name_));
  map_ = &map;
  id_ = id;
  block_ = *block;
  time_ = t0;
  for (auto& s : sensors_) s->attach(*this, map.take_sensor_id());
}

ConstantVelocityRobot::ConstantVelocityRobot(models::ConstantVelocityParams params, std::string name)
    : Robot(std::move(name)), params_(params) {
  params_.validate();
}

filter::BlockLayout ConstantVelocityRobot::static_layout() {
  return filter::BlockLayout::euclidean(3).then_quaternion().then_euclidean(3).then_euclidean(3);
}

bool ConstantVelocityRobot::predict_to(TimeNs t) {
  if (t < time_) return false;
  if (t == time_) return true;
  const double dt = to_seconds(t - time_);
  filter::State& state = map_->state();
  const models::Vector13d x = state.mean(block_);
  models::constant_velocity_predict(x, dt, params_, x_tmp_, &F_, &Q_);
  state.mean(block_) = x_tmp_;
  state.predict(block_, F_, Q_);
  time_ = t;
  return true;
}

}  // namespace rtslam::slam
