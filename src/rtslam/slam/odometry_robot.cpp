#include "rtslam/slam/odometry_robot.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/slam/map.hpp"

namespace rtslam::slam {

OdometryRobot::OdometryRobot(models::OdometryParams params, std::string name)
    : Robot(std::move(name)), params_(params) {
  params_.validate();
}

filter::BlockLayout OdometryRobot::static_layout() { return filter::BlockLayout::euclidean(3).then_quaternion(); }

void OdometryRobot::add_input(const RawData& input) {
  const auto* o = dynamic_cast<const OdometryData*>(&input);
  if (o == nullptr) {
    throw DataError(fmt::format("robot '{}': its input at t = {} ns is not an odometry reading", name(), input.t));
  }
  if (!(o->t > o->t_from)) {
    throw DataError(fmt::format("robot '{}': odometry increment from t = {} ns to t = {} ns does not go forward",
                                name(), o->t_from, o->t));
  }
  if (last_t_ && o->t_from < *last_t_) {
    throw DataError(fmt::format("robot '{}': odometry increment from t = {} ns starts before the previous one ends "
                                "(t = {} ns)",
                                name(), o->t_from, *last_t_));
  }
  if (!o->dp.allFinite() || !o->dtheta.allFinite()) {
    throw DataError(fmt::format("robot '{}': odometry increment at t = {} ns is not finite", name(), o->t));
  }
  last_t_ = o->t;
  if (map_ != nullptr && o->t <= time_) return;  // wholly before the robot's time
  pending_.push_back(Increment{o->t_from, o->t, {o->dp, o->dtheta, to_seconds(o->t - o->t_from)}});
}

bool OdometryRobot::predict_to(TimeNs t) {
  if (t < time_) return false;
  if (t == time_) return true;
  if (!last_t_ || *last_t_ < t) {
    throw DataError(fmt::format("robot '{}': the odometry does not cover t = {} ns (last reading at {})", name(), t,
                                last_t_ ? fmt::format("{} ns", *last_t_) : std::string("none")));
  }
  filter::State& state = map_->state();
  x_ = state.mean(block_);
  const bool fej = fej_ && fej_valid_;
  Phi_.setIdentity();
  Qacc_.setZero();
  while (time_ < t) {
    while (!pending_.empty() && pending_.front().t1 <= time_) pending_.pop_front();
    const Increment& inc = pending_.front();
    if (inc.t0 > time_) {  // a gap between readings: no motion
      time_ = std::min(inc.t0, t);
      continue;
    }
    const TimeNs t1 = std::min(inc.t1, t);
    const models::OdometryIncrement part =
        inc.u.scaled(static_cast<double>(t1 - time_) / static_cast<double>(inc.t1 - inc.t0));
    if (fej) {  // the transition along the first estimate, the mean from the corrected one
      models::odometry_predict(fej_x_, part, fej_x_, &F_, &G_);
      models::odometry_predict(x_, part, x_);
    } else {
      models::odometry_predict(x_, part, x_, &F_, &G_);
    }
    U_ = models::odometry_input_covariance(part, params_);
    tmp_.noalias() = F_ * Phi_;
    Phi_ = tmp_;
    tmp_.noalias() = F_ * Qacc_;
    Qacc_.noalias() = tmp_ * F_.transpose();
    tmp_.noalias() = G_ * U_;
    Qacc_.noalias() += tmp_ * G_.transpose();
    ++steps_;
    time_ = t1;
    if (t1 == inc.t1) pending_.pop_front();
  }
  state.mean(block_) = x_;
  fej_x_ = x_;  // the first estimate at t: this prediction, before the corrections at t
  fej_valid_ = true;
  if (state.nullspace_dim() > 0) {
    nullspace(x_, N_);
    state.predict_constrained(block_, Phi_, Qacc_, N_, models::OdometryIndex::kDth, 3);  // attitude columns
  } else {
    state.predict(block_, Phi_, Qacc_);
  }
  return true;
}

void OdometryRobot::nullspace(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::MatrixXd> N) const {
  N.setZero();
  N.block<3, 3>(0, 0).setIdentity();
  N.block<3, 3>(0, 3) = -math::skew(x.head<3>());
  N.block<3, 3>(3, 3) = math::quat_from_wxyz(x.segment<4>(3)).toRotationMatrix().transpose();
}

}  // namespace rtslam::slam
