#include "rtslam/sim/point_scene.hpp"

#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/sim/simulation.hpp"
#include "rtslam/sim/world.hpp"

namespace rtslam::sim {

void PointSceneOptions::validate(const std::string& where) const {
  require_bound(duration_s > 0.0 && duration_s <= 3600.0, where, "duration_s", duration_s, "in (0, 3600] s");
  require_bound(rate_hz > 0.0 && rate_hz <= 1000.0, where, "rate_hz", rate_hz, "in (0, 1000] Hz");
  require_bound(n_points >= 10 && n_points <= 100000, where, "n_points", n_points, "in [10, 100000]");
  require_bound(sigma_px >= 0.0 && sigma_px <= 100.0, where, "sigma_px", sigma_px, "in [0, 100] px");
  require_bound(margin_px >= 0.0 && margin_px <= 1000.0, where, "margin_px", margin_px, "in [0, 1000] px");
  if (!((room_max - room_min).minCoeff() > 0.5)) throw ConfigError(where + ": the room must be larger than 0.5 m");
}

namespace {

const PointSceneOptions& validated(const PointSceneOptions& o) {
  o.validate("point scene");
  return o;
}

io::CameraCalibration scene_camera(double rate_hz) {
  io::CameraCalibration c = SimConfig::euroc_cam0();
  c.rate_hz = rate_hz;
  return c;
}

}  // namespace

PointScene::PointScene(const PointSceneOptions& options)
    : options_(validated(options)),
      rng_(options.seed),
      points_(points_on_box_faces(options.room_min, options.room_max, options.n_points, rng_)),
      trajectory_(make_handheld(options.seed, 0.5 * (options.room_min + options.room_max), options.duration_s)),
      camera_(scene_camera(options.rate_hz)),
      model_(to_intrinsics(camera_)),
      T_RS_(math::Pose::from_isometry(camera_.T_RS)),
      n_frames_(static_cast<int>(std::floor(options.duration_s * options.rate_hz)) + 1) {}

TimeNs PointScene::frame_time(int k) const { return trajectory_->t_begin() + from_seconds(k / options_.rate_hz); }

math::Pose PointScene::start_pose() const {
  const KinematicState s = trajectory_->at(trajectory_->t_begin());
  return math::Pose{s.q_WR, s.p_WR};
}

void PointScene::measure(int k, std::vector<ScenePoint>& out) {
  if (k != next_frame_)
    throw std::logic_error(fmt::format("point scene: frame {} measured, frame {} expected (frames go in order, once)", k,
                                 next_frame_));
  ++next_frame_;
  out.clear();
  const KinematicState s = trajectory_->at(frame_time(k));
  const math::Pose T_WS = math::Pose{s.q_WR, s.p_WR} * T_RS_;
  for (size_t i = 0; i < points_.size(); ++i) {
    Eigen::Vector2d z;
    if (!model_.project(T_WS.inverse_transform(points_[i]), z)) continue;
    z += Eigen::Vector2d(randn(rng_), randn(rng_)) * options_.sigma_px;
    if (!model_.in_image(z, options_.margin_px)) continue;
    out.push_back({static_cast<int>(i), z});
  }
}

Trajectory PointScene::groundtruth() const {
  Trajectory gt;
  gt.source = "rtslam points demo: simulated truth";
  gt.poses.reserve(static_cast<size_t>(n_frames_));
  for (int k = 0; k < n_frames_; ++k) {
    const KinematicState s = trajectory_->at(frame_time(k));
    StampedPose p;
    p.t = frame_time(k);
    p.p_WR = s.p_WR;
    p.q_WR = s.q_WR;
    p.v_WR = s.v_WR;
    gt.poses.push_back(p);
  }
  return gt;
}

}  // namespace rtslam::sim
