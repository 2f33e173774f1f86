#include "rtslam/slam/sensor.hpp"

#include <algorithm>

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
  if (time_offset_prior_var_ && time_block_ == filter::kNoBlock && robot.in_map()) {
    // A clock offset does not move with the world either: zero rows of the unobservable basis.
    const auto b = robot.map().state().add_block(filter::BlockLayout::euclidean(1), Eigen::VectorXd::Zero(1),
                                                 Eigen::MatrixXd::Constant(1, 1, *time_offset_prior_var_));
    if (!b) throw ConfigError(fmt::format("sensor '{}': the map has no room for its time offset", name_));
    time_block_ = *b;
    applied_shift_ = 0;
  }
}

void Sensor::estimate_time_offset(double prior_var_s2, double max_shift_s) {
  RTSLAM_CHECK(time_block_ == filter::kNoBlock && (robot_ == nullptr || !robot_->in_map()),
               fmt::format("sensor '{}': time offset estimation must be requested before the robot joins a map", name_));
  RTSLAM_CHECK(prior_var_s2 > 0.0 && max_shift_s >= 0.0,
               fmt::format("sensor '{}': time offset prior variance {} must be > 0 and max shift {} >= 0", name_,
                           prior_var_s2, max_shift_s));
  time_offset_prior_var_ = prior_var_s2;
  max_shift_ = from_seconds(max_shift_s);
}

double Sensor::time_offset(const Eigen::VectorXd& mean) const {
  if (time_block_ == filter::kNoBlock) return 0.0;
  return mean[robot_->map().state().block(time_block_).ambient_offset];
}

TimeNs Sensor::time_shift(const Eigen::VectorXd& mean) const {
  if (time_block_ == filter::kNoBlock) return 0;
  const double max_s = to_seconds(max_shift_);
  return from_seconds(std::clamp(time_offset(mean), -max_s, max_s));
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
                                 Eigen::Matrix<double, 6, 6>* J_TWS_TRS, Eigen::Matrix<double, 6, 1>* J_TWS_td) const {
  const math::Pose T_WR = robot_->pose(mean);
  Eigen::Matrix<double, 6, 1> xi;
  if (time_block_ == filter::kNoBlock || !robot_->pose_rate(mean, xi)) {
    if (J_TWS_td != nullptr) J_TWS_td->setZero();
    return math::compose_poses(T_WR, T_RS(mean), J_TWS_TWR, block_ == filter::kNoBlock ? nullptr : J_TWS_TRS);
  }
  // T_WR' = (p + s v, q ⊗ Exp(s ω)), s = δt_d − applied shift (header comment).
  const double s = time_offset(mean) - to_seconds(applied_shift_);
  const Eigen::Quaterniond dq = math::exp_so3(s * xi.tail<3>());
  const math::Pose T_WR_t{(T_WR.q * dq).normalized(), T_WR.p + s * xi.head<3>()};
  const bool want_J = J_TWS_TWR != nullptr || J_TWS_td != nullptr;
  Eigen::Matrix<double, 6, 6> J_TWS_TWRt;
  const math::Pose T_WS = math::compose_poses(T_WR_t, T_RS(mean), want_J ? &J_TWS_TWRt : nullptr,
                                              block_ == filter::kNoBlock ? nullptr : J_TWS_TRS);
  if (J_TWS_TWR != nullptr) {
    // ∂T_WR'/∂T_WR: δp unchanged; q ⊗ Exp(δθ) ⊗ dq = q ⊗ dq ⊗ Exp(R(dq)ᵀ δθ).
    *J_TWS_TWR = J_TWS_TWRt;
    J_TWS_TWR->rightCols<3>() = J_TWS_TWRt.rightCols<3>() * dq.toRotationMatrix().transpose();
  }
  // d/dδt_d of (p + s v, q ⊗ Exp(s ω)) in the tangent at T_WR': (v, ω) exactly (Jr(sω) ω = ω).
  if (J_TWS_td != nullptr) J_TWS_td->noalias() = J_TWS_TWRt * xi;
  return T_WS;
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
