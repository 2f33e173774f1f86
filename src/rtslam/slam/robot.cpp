#include "rtslam/slam/robot.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/slam/health.hpp"
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

void Robot::allocate_block(const Eigen::VectorXd& mean, const Eigen::MatrixXd& cov) {
  std::optional<filter::BlockId> block;
  if (map_->state().nullspace_dim() > 0) {
    RTSLAM_CHECK(map_->state().nullspace_dim() == kNullspaceDim,
                 fmt::format("robot '{}': the map tracks {} unobservable directions, robots give {}", name_,
                             map_->state().nullspace_dim(), kNullspaceDim));
    Eigen::MatrixXd N(layout().tangent_size(), kNullspaceDim);
    nullspace(mean, N);
    block = map_->state().add_block(layout(), mean, cov, N);
  } else {
    block = map_->state().add_block(layout(), mean, cov);
  }
  if (!block) throw ConfigError(fmt::format("robot '{}': the map has no room for its state", name_));
  block_ = *block;
}

void Robot::assign_sensor_ids(Map& map) {
  for (auto& s : sensors_)
    if (s->id() < 0) s->attach(*this, map.take_sensor_id());
}

void Robot::add_input(const RawData& input) {
  throw DataError(fmt::format("robot '{}' takes no proprioceptive input (datum at t = {} ns)", name_, input.t));
}

Eigen::VectorXd Robot::reanchor(const Eigen::VectorXd& x0, const Eigen::VectorXd& last_good,
                                const HealthOptions& /*health*/) const {
  Eigen::VectorXd x = x0;
  x.head<7>() = last_good.head<7>();
  return x;
}

void Robot::attach(Map& map, int id, const Eigen::VectorXd& mean, const Eigen::MatrixXd& cov, TimeNs t0) {
  RTSLAM_CHECK(map_ == nullptr, "robot already attached to a map");
  map_ = &map;
  try {
    allocate_block(mean, cov);
  } catch (...) {
    map_ = nullptr;
    throw;
  }
  id_ = id;
  time_ = t0;
  for (auto& s : sensors_) s->attach(*this, s->id() >= 0 ? s->id() : map.take_sensor_id());
}

void Robot::reset(const Eigen::VectorXd& mean, const Eigen::MatrixXd& cov, TimeNs t) {
  RTSLAM_CHECK(map_ != nullptr, "reset: robot not in a map");
  RTSLAM_CHECK(t >= time_, "reset: a robot cannot go back in time");
  time_ = t;
  map_->state().remove_block(block_);
  allocate_block(mean, cov);
  fej_valid_ = false;
  restarted();
}

void Robot::scale_lengths(double, const Eigen::Vector3d&, Eigen::Ref<Eigen::VectorXd>, Eigen::Ref<Eigen::VectorXd>) {
  RTSLAM_CHECK(false, "Robot::scale_lengths: this robot's state cannot change its unit of length");
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
  if (fej_ && fej_valid_) {
    models::constant_velocity_predict(x, dt, params_, x_tmp_);
    models::constant_velocity_predict(fej_x_, dt, params_, fej_tmp_, &F_, &Q_);
  } else {
    models::constant_velocity_predict(x, dt, params_, x_tmp_, &F_, &Q_);
  }
  fej_x_ = x_tmp_;
  fej_valid_ = true;
  state.mean(block_) = x_tmp_;
  if (state.nullspace_dim() > 0) {
    nullspace(x_tmp_, N_);
    state.predict_constrained(block_, F_, Q_, N_, 3, 3);  // the attitude-error columns
  } else {
    state.predict(block_, F_, Q_);
  }
  time_ = t;
  return true;
}

bool ConstantVelocityRobot::pose_rate(const Eigen::VectorXd& mean, Eigen::Matrix<double, 6, 1>& xi) const {
  using I = models::ConstantVelocityIndex;
  const int a = map_->state().block(block_).ambient_offset;
  xi << mean.segment<3>(a + I::kV), mean.segment<3>(a + I::kW);
  return true;
}

namespace {
// Rows of the global-frame basis [t φ] for a pose [p q] at the start of a robot block (tangent [δp δθ]).
void pose_nullspace(const Eigen::Vector3d& p, const Eigen::Vector4d& q_wxyz, Eigen::Ref<Eigen::MatrixXd> N) {
  N.setZero();
  N.block<3, 3>(0, 0).setIdentity();
  N.block<3, 3>(0, 3) = -math::skew(p);
  N.block<3, 3>(3, 3) = math::quat_from_wxyz(q_wxyz).toRotationMatrix().transpose();
}
}  // namespace

void ConstantVelocityRobot::nullspace(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::MatrixXd> N) const {
  pose_nullspace(x.head<3>(), x.segment<4>(3), N);
  N.block<3, 3>(6, 3) = -math::skew(x.segment<3>(7));
}

InertialRobot::InertialRobot(models::InertialParams params, std::string name)
    : Robot(std::move(name)), params_(params) {
  params_.validate();
}

filter::BlockLayout InertialRobot::static_layout() {
  return filter::BlockLayout::euclidean(3).then_quaternion().then_euclidean(3).then_euclidean(3).then_euclidean(3).then_euclidean(3);
}

void InertialRobot::add_imu(TimeNs t, const models::ImuMeasurement& m) {
  const std::optional<TimeNs> last = imu_coverage();
  if (last && t <= *last) {
    throw DataError(fmt::format("robot '{}': IMU sample at t = {} ns is not after the previous one (t = {} ns)", name(),
                                t, *last));
  }
  if (!m.accel.allFinite() || !m.gyro.allFinite()) {
    throw DataError(fmt::format("robot '{}': IMU sample at t = {} ns is not finite", name(), t));
  }
  if (map_ != nullptr && t <= time_) {
    prev_ = Sample{t, m};  // before the robot's time: only the reading at time_ may need it
    return;
  }
  pending_.push_back(Sample{t, m});
}

void InertialRobot::add_input(const RawData& input) {
  const auto* imu = dynamic_cast<const ImuData*>(&input);
  if (imu == nullptr) {
    throw DataError(fmt::format("robot '{}': its input at t = {} ns is not an IMU sample", name(), input.t));
  }
  add_imu(imu->t, imu->m);
}

Eigen::VectorXd InertialRobot::reanchor(const Eigen::VectorXd& x0_in, const Eigen::VectorXd& last_good,
                                        const HealthOptions& health) const {
  using I = models::InertialIndex;
  Eigen::VectorXd x0 = x0_in;
  // Heading: of the body axis most orthogonal to gravity, in both frames.
  const Eigen::Quaterniond q_new = math::quat_from_wxyz(x0.segment<4>(I::kQ));
  const Eigen::Quaterniond q_old = math::quat_from_wxyz(last_good.segment<4>(I::kQ));
  const Eigen::Vector3d up_R = q_new.conjugate() * Eigen::Vector3d::UnitZ();
  int k = 0;
  up_R.cwiseAbs().minCoeff(&k);
  const Eigen::Vector3d h_new = q_new * Eigen::Vector3d::Unit(k), h_old = q_old * Eigen::Vector3d::Unit(k);
  const Eigen::Quaterniond Rz(Eigen::AngleAxisd(std::atan2(h_old.y(), h_old.x()) - std::atan2(h_new.y(), h_new.x()),
                                                Eigen::Vector3d::UnitZ()));
  x0.segment<3>(I::kP) = last_good.segment<3>(I::kP);
  x0.segment<4>(I::kQ) = math::quat_to_wxyz((Rz * q_new).normalized());
  x0.segment<3>(I::kV) = Rz * x0.segment<3>(I::kV);
  x0.segment<3>(I::kG) = Rz * x0.segment<3>(I::kG);
  if (last_good.segment<3>(I::kAb).norm() <= 0.5 * health.max_accel_bias &&
      last_good.segment<3>(I::kWb).norm() <= 0.5 * health.max_gyro_bias) {
    x0.segment<3>(I::kAb) = last_good.segment<3>(I::kAb);
    if (x0.segment<3>(I::kWb).isZero()) x0.segment<3>(I::kWb) = last_good.segment<3>(I::kWb);
  }
  return x0;
}

std::optional<TimeNs> InertialRobot::imu_coverage() const {
  if (!pending_.empty()) return pending_.back().t;
  if (prev_) return prev_->t;
  return std::nullopt;
}

models::ImuMeasurement InertialRobot::lerp(const Sample& a, const Sample& b, TimeNs t) {
  if (t == a.t) return a.m;
  if (t == b.t) return b.m;
  const double s = static_cast<double>(t - a.t) / static_cast<double>(b.t - a.t);
  models::ImuMeasurement m;
  m.accel = a.m.accel + s * (b.m.accel - a.m.accel);
  m.gyro = a.m.gyro + s * (b.m.gyro - a.m.gyro);
  return m;
}

bool InertialRobot::predict_to(TimeNs t) {
  if (t < time_) return false;
  if (t == time_) return true;
  const std::optional<TimeNs> covered = imu_coverage();
  if (!covered || *covered < t) {
    throw DataError(fmt::format("robot '{}': the IMU does not cover t = {} ns (last sample at {})", name(), t,
                                covered ? fmt::format("{} ns", *covered) : std::string("none")));
  }
  filter::State& state = map_->state();
  x_ = state.mean(block_);
  const bool fej = fej_ && fej_valid_;
  // At rest (the latest frame's verdict, for this prediction only) and the interval's samples agree: hold.
  const bool hold = at_rest_ && interval_at_rest(t);
  at_rest_ = false;
  Phi_.setIdentity();
  Qacc_.setZero();
  while (time_ < t) {
    // Samples at or before time_ only serve the reading at time_.
    while (!pending_.empty() && pending_.front().t <= time_) {
      prev_ = pending_.front();
      pending_.pop_front();
    }
    const Sample& next = pending_.front();
    const Sample& before = prev_ ? *prev_ : next;  // no earlier sample (start of the stream): hold the first
    const models::ImuMeasurement m0 = lerp(before, next, time_);
    const TimeNs t1 = std::min(next.t, t);
    const models::ImuMeasurement m1 = lerp(before, next, t1);
    gyro_sum_ += (0.5 * static_cast<double>(t1 - time_)) * (m0.gyro + m1.gyro);
    gyro_span_ += t1 - time_;
    if (hold) {
      // The state stays; only the biases random-walk.
      using I = models::InertialIndex;
      const double dt = to_seconds(t1 - time_);
      Qacc_.diagonal().segment<3>(I::kDab).array() +=
          params_.accelerometer_random_walk * params_.accelerometer_random_walk * dt;
      Qacc_.diagonal().segment<3>(I::kDwb).array() += params_.gyroscope_random_walk * params_.gyroscope_random_walk * dt;
      ++held_;
    } else {
      if (fej) {
        // The transition along the first-estimate states (fej_x_), the mean from the corrected one.
        models::inertial_predict(fej_x_, m0, m1, to_seconds(t1 - time_), params_, fej_next_, &F_, &Q_);
        fej_x_ = fej_next_;
        models::inertial_predict(x_, m0, m1, to_seconds(t1 - time_), params_, x_);
      } else {
        models::inertial_predict(x_, m0, m1, to_seconds(t1 - time_), params_, x_, &F_, &Q_);
      }
      tmp_.noalias() = F_ * Phi_;
      Phi_ = tmp_;
      tmp_.noalias() = F_ * Qacc_;
      Qacc_.noalias() = tmp_ * F_.transpose();
      Qacc_ += Q_;
      ++steps_;
    }
    time_ = t1;
    if (t1 == next.t) {
      prev_ = next;
      pending_.pop_front();
    }
  }
  if (gyro_span_ >= from_seconds(0.01)) {
    gyro_mean_ = gyro_sum_ / static_cast<double>(gyro_span_);
    gyro_mean_valid_ = true;
    gyro_sum_.setZero();
    gyro_span_ = 0;
  }
  state.mean(block_) = x_;
  fej_x_ = x_;  // the first estimate at t: this prediction, before the corrections at t
  fej_valid_ = true;
  if (state.nullspace_dim() > 0) {
    nullspace(x_, N_);
    state.predict_constrained(block_, Phi_, Qacc_, N_, models::InertialIndex::kDth, 3);  // attitude columns
  } else {
    state.predict(block_, Phi_, Qacc_);
  }
  return true;
}

bool InertialRobot::interval_at_rest(TimeNs t) const {
  using I = models::InertialIndex;
  const int a = map_->state().block(block_).ambient_offset;
  const Eigen::VectorXd& mean = map_->state().mean_vector();
  const math::Pose T = pose(mean);
  const Eigen::Vector3d ab = mean.segment<3>(a + I::kAb), wb = mean.segment<3>(a + I::kWb);
  // At rest the accelerometer reads −g in the body frame (plus its bias) and the gyro its bias.
  const Eigen::Vector3d f_rest = T.q.conjugate() * (-mean.segment<3>(a + I::kG)) + ab;
  for (std::size_t k = 0; k < pending_.size(); ++k) {
    const Sample& s = pending_[k];
    if ((s.m.gyro - wb).norm() > kRestGyro || (s.m.accel - f_rest).norm() > kRestAccel) return false;
    if (s.t >= t) break;
  }
  return true;
}

bool InertialRobot::pose_rate(const Eigen::VectorXd& mean, Eigen::Matrix<double, 6, 1>& xi) const {
  using I = models::InertialIndex;
  // The reading at time_: between the latest sample at or before it and the first one after it.
  const Sample* after = nullptr;
  for (std::size_t k = 0; k < pending_.size(); ++k) {
    if (pending_[k].t > time_) {
      after = &pending_[k];
      break;
    }
  }
  const Sample* before = prev_ && prev_->t <= time_ ? &*prev_ : nullptr;
  Eigen::Vector3d gyro;
  if (before != nullptr && after != nullptr) gyro = lerp(*before, *after, time_).gyro;
  else if (before != nullptr) gyro = before->m.gyro;
  else if (after != nullptr) gyro = after->m.gyro;
  else return false;
  // The mean reading over the last prediction interval, the rotation increment over dt: the reading of one instant
  // carries the vibration (rotors) that the pose does not follow at the image rate. Measured on the recorded V1_01
  // flight (docs/configuration.md, camera/time_offset): with the reading at t the estimate settled at -0.47 ms and
  // the ATE rose from 1.01 to 1.25 cm; with the mean, -0.67 ms and 0.93 cm.
  if (gyro_mean_valid_) gyro = gyro_mean_;
  const int a = map_->state().block(block_).ambient_offset;
  xi << mean.segment<3>(a + I::kV), gyro - mean.segment<3>(a + I::kWb);
  return true;
}

void InertialRobot::nullspace(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::MatrixXd> N) const {
  using I = models::InertialIndex;
  pose_nullspace(x.head<3>(), x.segment<4>(I::kQ), N);
  N.block<3, 3>(I::kDv, 3) = -math::skew(x.segment<3>(I::kV));
  N.block<3, 3>(I::kDg, 3) = -math::skew(x.segment<3>(I::kG));
}

}  // namespace rtslam::slam
