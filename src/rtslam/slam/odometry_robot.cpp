#include "rtslam/slam/odometry_robot.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/slam/map.hpp"

namespace rtslam::slam {

void OdometryScaleOptions::validate() const {
  if (!(window_m > 0.0 && window_m <= 1000.0)) {
    throw ConfigError(fmt::format("odometry/rescale_window = {} must be in (0, 1000] m", window_m));
  }
  if (!(max_se > 0.0 && max_se <= 1.0)) {
    throw ConfigError(fmt::format("odometry/rescale_max_se = {} must be in (0, 1]", max_se));
  }
  if (!(min_z >= 0.0 && min_z <= 100.0)) {
    throw ConfigError(fmt::format("odometry/rescale_min_z = {} must be in [0, 100]", min_z));
  }
}

OdometryRobot::OdometryRobot(models::OdometryParams params, std::string name, OdometryScaleOptions scale)
    : Robot(std::move(name)), params_(params), scale_(scale) {
  params_.validate();
  scale_.validate();
}

void OdometryRobot::scale_lengths(double c, const Eigen::Vector3d& centre, Eigen::Ref<Eigen::VectorXd> mean,
                                  Eigen::Ref<Eigen::VectorXd> d) {
  d.setOnes();
  d.head<3>().setConstant(c);
  mean.head<3>() = centre + c * (mean.head<3>() - centre);
  fej_x_.head<3>() = centre + c * (fej_x_.head<3>() - centre);
  window_p_ = centre + c * (window_p_ - centre);  // the current window and the windows so far, in the new unit
  sum_os_ *= c;
  sum_ss_ *= c * c;
}

bool OdometryRobot::keeps_scale() const { return scale_.enabled && (map_ == nullptr || map_->robots().size() == 1); }

void OdometryRobot::restarted() {
  window_open_ = false;  // a new map, whose scale is its own
  start_p_.reset();
  sum_os_ = sum_ss_ = 0.0;
}

void OdometryRobot::keep_scale() {
  if (!scale_.enabled || map_->robots().size() != 1) return;
  const auto x = map_->state().mean(block_);  // the posterior at time_
  const Eigen::Vector3d p = x.head<3>();
  if (!start_p_) {
    start_p_ = p;
    map_->reserve_length_scaling();  // at the start: a rescale does not allocate
  }
  if (window_open_ && odo_length_ >= scale_.window_m) {
    const Eigen::Vector3d ds = p - window_p_;
    const Eigen::Vector3d d_odo = window_R_ * odo_p_;
    const double var = params_.sigma_p * params_.sigma_p * odo_time_ + params_.k_p * params_.k_p * odo_length_;
    if (var > 0.0) {
      sum_os_ += d_odo.dot(ds) / var;
      sum_ss_ += ds.squaredNorm() / var;
    }
    window_open_ = false;
    const double se = sum_ss_ > 0.0 ? 1.0 / std::sqrt(sum_ss_) : 1.0;
    const double s = sum_ss_ > 0.0 ? sum_os_ / sum_ss_ : 1.0;
    // Rescaled once the odometry knows the scale well enough (and, with min_z > 0, only when its factor differs
    // significantly from the map's).
    if (se < scale_.max_se && std::abs(s - 1.0) > scale_.min_z * se && std::isfinite(s) && s > 0.0) {
      const double c = std::clamp(s, 0.5, 2.0);
      if (map_->scale_lengths(c, *start_p_)) {
        ++rescales_;
        rescale_product_ *= c;
        logger("slam")->debug("t = {:.3f} s: map rescaled by {:.4f} to the odometry's scale (standard error {:.1f} %)",
                              to_seconds(time_), c, 100.0 * se);
      } else {
        scale_.enabled = false;
        logger("slam")->warn(
            "robot '{}': the map's scale cannot be kept at the odometry's (odometry/rescale): its "
            "state holds blocks that cannot change their unit of length",
            name());
      }
    }
  }
  if (!window_open_) {
    window_open_ = true;
    window_p_ = map_->state().mean(block_).head<3>();
    window_R_ = math::quat_from_wxyz(x.segment<4>(3)).toRotationMatrix();
    odo_p_.setZero();
    odo_R_.setIdentity();
    odo_length_ = odo_time_ = 0.0;
  }
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
  keep_scale();
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
    if (window_open_) {  // the odometry's own dead reckoning over the scale window
      odo_p_ += odo_R_ * part.dp;
      odo_R_ = odo_R_ * math::exp_so3(part.dtheta).toRotationMatrix();
      odo_length_ += part.dp.norm();
      odo_time_ += part.dt;
    }
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
