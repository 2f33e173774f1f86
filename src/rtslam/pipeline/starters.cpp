#include "rtslam/pipeline/starters.hpp"

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/models/robots/constant_velocity.hpp"

namespace rtslam::pipeline {

using strategies::ImuWindowSample;
using strategies::InertialStart;

std::vector<ImuWindowSample> imu_window(const RingBuffer<slam::ImuData>& inputs) {
  std::vector<ImuWindowSample> w;
  w.reserve(inputs.size());
  for (std::size_t k = 0; k < inputs.size(); ++k) w.push_back({inputs[k].t, inputs[k].m});
  return w;
}

PoseStarter::PoseStarter(double initial_velocity_std, std::optional<KnownLandmarkSet> known,
                         std::optional<Eigen::VectorXd> initial, Eigen::MatrixXd initial_cov)
    : known_(std::move(known)) {
  using I = models::ConstantVelocityIndex;
  x0_ = Eigen::VectorXd::Zero(I::kAmbientSize);
  x0_.segment<4>(I::kQ) << 1.0, 0.0, 0.0, 0.0;
  // The gauge: the first pose is the world frame, with zero covariance.
  P0_ = Eigen::MatrixXd::Zero(I::kTangentSize, I::kTangentSize);
  P0_.bottomRightCorner<6, 6>() = initial_velocity_std * initial_velocity_std * Eigen::MatrixXd::Identity(6, 6);
  if (known_) {
    x0_ = known_->robot_mean;
    P0_ = known_->robot_cov;
  } else if (initial) {
    // Another robot than the constant-velocity one ([p q ...]: the odometry robot's [p q]) gives its covariance.
    RTSLAM_CHECK(initial_cov.size() > 0 ? initial->size() >= 7 && initial_cov.rows() == initial->size() - 1 &&
                                              initial_cov.cols() == initial_cov.rows()
                                        : initial->size() == I::kAmbientSize,
                 "PoseStarter: the initial state has 13 entries, or its covariance one row fewer than its entries");
    x0_ = *initial;
    if (initial_cov.size() > 0) P0_ = initial_cov;
  }
}

std::optional<slam::RobotStart> PoseStarter::offer(const slam::RawData& datum, const RingBuffer<slam::ImuData>&) {
  slam::RobotStart s;
  s.x = x0_;
  s.P = P0_;
  s.t = datum.t;
  s.replay.push_back(&datum);
  return s;
}

void PoseStarter::started(slam::Map& map, slam::Robot& robot, bool first) {
  if (known_ && first) known_added_ = add_known_landmarks(map, *robot.sensors().front(), *known_);
}

InertialStarter::InertialStarter(const InertialOptions& options, const slam::Sensor& camera,
                                 const models::CameraIntrinsics& intrinsics, const math::Pose& T_RS,
                                 strategies::ActiveSearchDataManager* dm)
    : o_(options), sensor_(camera), camera_(intrinsics), T_RS_(T_RS), dm_(dm) {}

void InertialStarter::restart() {
  first_image_t_ = -1;
  window_.clear();
  wait_ = Wait::Nothing;
}

std::string InertialStarter::waiting_for() const {
  const strategies::ViInitOptions& v = o_.vi_init;
  switch (wait_) {
    case Wait::Nothing: return {};
    case Wait::ImuWindow:
      return fmt::format("{:.2f} s of IMU data before an image (imu/init_window; {})", o_.init_window_s,
                         wait_imu_first_ < 0 ? std::string("no IMU sample yet")
                                             : fmt::format("the IMU starts at {:.3f} s", to_seconds(wait_imu_first_)));
    case Wait::ViWindow:
      return fmt::format("{:.2f} s of images for the visual-inertial start (imu/vi_init/window; {} image(s) over "
                         "{:.2f} s)",
                         v.window_s, window_.size(),
                         window_.empty() ? 0.0 : to_seconds(window_.back().t - window_.front().t));
    case Wait::ViAccepted:
      return fmt::format("a window the visual-inertial start accepts (the last one: {}), or images past {:.3f} s, "
                         "where the IMU-only start takes over (imu/vi_init/max_window + max_wait after the first "
                         "image at {:.3f} s)",
                         wait_reason_, to_seconds(first_image_t_ + from_seconds(v.max_window_s + v.max_wait_s)),
                         to_seconds(first_image_t_));
  }
  return {};
}

void InertialStarter::started(slam::Map&, slam::Robot&, bool) {
  if (depth_hint_ && dm_ != nullptr) dm_->set_depth_hint(*depth_hint_);
  depth_hint_.reset();
  window_.clear();
  window_.shrink_to_fit();
  wait_ = Wait::Nothing;
}

std::optional<slam::RobotStart> InertialStarter::imu_only(TimeNs t, const RingBuffer<slam::ImuData>& inputs,
                                                          std::string prefix) {
  if (inputs.empty() || inputs.front().t > t - from_seconds(o_.init_window_s)) {
    wait_ = Wait::ImuWindow;
    wait_imu_first_ = inputs.empty() ? -1 : inputs.front().t;
    return std::nullopt;
  }
  const InertialStart s0 = initialize_inertial(imu_window(inputs), t, o_);
  slam::RobotStart s;
  s.x = s0.x;
  s.P = s0.P;
  s.t = t;
  s.description = prefix + s0.describe();
  logger("slam")->info("inertial robot: {}", s.description);
  s.replay.push_back(offered_);
  return s;
}

std::optional<slam::RobotStart> InertialStarter::offer(const slam::RawData& datum,
                                                       const RingBuffer<slam::ImuData>& inputs) {
  if (datum.sensor_id != sensor_.id()) {  // another camera: the start uses the first one's images
    ++skipped_;
    return std::nullopt;
  }
  offered_ = &datum;
  sensor_id_ = datum.sensor_id;
  if (!o_.vi_init.enabled) {
    std::optional<slam::RobotStart> s = imu_only(datum.t, inputs, "");
    if (!s && ++skipped_ == 1) {
      logger("slam")->info("waiting for {:.2f} s of IMU data before the first image to start the inertial robot",
                           o_.init_window_s);
    }
    return s;
  }
  const auto* image = dynamic_cast<const MatImage*>(&datum);
  if (image == nullptr) throw DataError("the inertial start takes images that own their pixels (MatImage)");
  window_.push_back(WindowImage{datum.t, image->mat});
  return try_visual_inertial(inputs);
}

// The visual-inertial start over the window: a start at the window's first image (its images are then replayed).
// While it fails the window slides; after vi_init/max_wait of failures the IMU-only start takes over at the newest
// image.
std::optional<slam::RobotStart> InertialStarter::try_visual_inertial(const RingBuffer<slam::ImuData>& inputs) {
  const strategies::ViInitOptions& v = o_.vi_init;
  if (first_image_t_ < 0) first_image_t_ = window_.front().t;
  if (window_.back().t - window_.front().t < from_seconds(v.window_s)) {
    wait_ = Wait::ViWindow;
    return std::nullopt;
  }
  const std::vector<strategies::ImuWindowSample> imu = imu_window(inputs);
  views_.clear();
  for (const WindowImage& w : window_) {
    views_.push_back({w.t, vision::ImageView{w.image.data, w.image.cols, w.image.rows, static_cast<int>(w.image.step[0])}});
  }
  const strategies::ViInitResult r = strategies::initialize_visual_inertial(views_, imu, camera_, T_RS_, v);
  if (r.kind != strategies::ViInitResult::Kind::Failed) {
    const strategies::InertialStart s0 = strategies::inertial_start_from_vi(r, o_);
    slam::RobotStart s;
    s.x = s0.x;
    s.P = s0.P;
    s.t = window_.front().t;
    s.description = r.describe() + "; " + s0.describe();
    logger("slam")->info("inertial robot: {}", s.description);
    if (r.kind == strategies::ViInitResult::Kind::Dynamic) depth_hint_ = r.median_depth_m;
    replay_.resize(window_.size());
    for (std::size_t k = 0; k < window_.size(); ++k) {
      if (!replay_[k]) replay_[k] = std::make_unique<MatImage>();
      replay_[k]->set(window_[k].t, sensor_id_, window_[k].image);
      s.replay.push_back(replay_[k].get());
    }
    return s;
  }
  logger("slam")->debug("visual-inertial start at t = {:.3f} s: {}", to_seconds(window_.front().t), r.reason);
  wait_ = Wait::ViAccepted;
  wait_reason_ = r.reason;
  if (window_.back().t - first_image_t_ > from_seconds(v.max_window_s + v.max_wait_s)) {
    std::optional<slam::RobotStart> s =
        imu_only(window_.back().t, inputs, fmt::format("visual-inertial start failed for {:.1f} s ({}): IMU-only start; ",
                                                       v.max_wait_s, r.reason));
    if (s) {
      skipped_ += static_cast<int>(window_.size()) - 1;
      return s;
    }
  }
  // Not enough parallax or excitation yet: the window grows (up to max_window); else it slides.
  if (r.needs_longer_window && window_.back().t - window_.front().t < from_seconds(v.max_window_s)) {
    return std::nullopt;
  }
  window_.erase(window_.begin());
  ++skipped_;
  return std::nullopt;
}

}  // namespace rtslam::pipeline
