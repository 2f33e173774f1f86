#include "rtslam/pipeline/point_demo.hpp"

#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/filter/state.hpp"
#include "rtslam/sim/trajectory.hpp"
#include "rtslam/sim/world.hpp"
#include "rtslam/pipeline/builder.hpp"
#include "rtslam/slam/system.hpp"

namespace rtslam::pipeline {

models::CameraIntrinsics euroc_cam0_intrinsics() {
  models::CameraIntrinsics c;
  c.width = 752;
  c.height = 480;
  c.fx = 458.654;
  c.fy = 457.296;
  c.cx = 367.215;
  c.cy = 248.375;
  c.model = models::DistortionModel::RadTan;
  c.coeffs = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  return c;
}

math::Pose euroc_cam0_T_RS() {
  Eigen::Matrix4d T;
  T << 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975, 0.999557249008, 0.0149672133247,
      0.025715529948, -0.064676986768, -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949, 0.0,
      0.0, 0.0, 1.0;
  Eigen::Isometry3d iso;
  iso.matrix() = T;
  // Re-orthonormalize the 3x3 (the YAML has 12 digits) so that the quaternion is exact.
  return math::Pose::from_isometry(iso);
}

strategies::KnownAssociationOptions demo_association_defaults() {
  strategies::KnownAssociationOptions a;
  a.prior.d_min = 1.0;
  return a;
}

strategies::MapPolicyOptions demo_map_defaults() {
  strategies::MapPolicyOptions m;
  m.forget_unseen_after_frames = 300;
  return m;
}

void PointDemoOptions::validate() const {
  const std::string w = "demo";
  require_bound(duration_s > 0.0 && duration_s <= 3600.0, w, "duration_s", duration_s, "in (0, 3600] s");
  require_bound(rate_hz > 0.0 && rate_hz <= 1000.0, w, "rate_hz", rate_hz, "in (0, 1000] Hz");
  require_bound(n_points >= 10 && n_points <= 100000, w, "n_points", n_points, "in [10, 100000]");
  require_bound(sigma_px >= 0.0 && sigma_px <= 100.0, w, "sigma_px", sigma_px, "in [0, 100] px");
  require_bound(initial_velocity_std > 0.0 && initial_velocity_std <= 100.0, w, "initial_velocity_std",
                initial_velocity_std, "in (0, 100]");
  require_bound(state_capacity >= 100 && state_capacity <= filter::StateOptions::kMaxTangentCapacity, w,
                "state_capacity", state_capacity,
                fmt::format("in [100, {}] covariance rows", filter::StateOptions::kMaxTangentCapacity));
  if (!((room_max - room_min).minCoeff() > 0.5)) throw ConfigError("demo: the room must be larger than 0.5 m");
  motion.validate();
  association.validate();
  map.validate();
}

namespace {

StampedPose stamped(TimeNs t, const math::Pose& T_WR) {
  StampedPose s;
  s.t = t;
  s.p_WR = T_WR.p;
  s.q_WR = T_WR.q;
  return s;
}

}  // namespace

// The demo's camera as a rig calibration (the builder makes the robot's sensors from a rig).
io::Rig demo_rig() {
  const models::CameraIntrinsics in = euroc_cam0_intrinsics();
  io::CameraCalibration cam;
  cam.name = "cam0";
  cam.width = in.width;
  cam.height = in.height;
  cam.fx = in.fx;
  cam.fy = in.fy;
  cam.cx = in.cx;
  cam.cy = in.cy;
  cam.distortion = io::DistortionModel::RadTan;
  cam.distortion_coeffs = in.coeffs;
  cam.T_RS = euroc_cam0_T_RS().isometry();
  io::Rig rig;
  rig.cameras.push_back(cam);
  return rig;
}

namespace {

// Collects the estimate and the statistics of each step.
struct DemoCollector final : slam::Observer {
  explicit DemoCollector(PointDemoResult& r) : result(r) {}
  void on_step(const slam::StepReport& s) override {
    result.frames.push_back(s.stats);
    StampedPose est = stamped(s.raw.t, s.robot.pose());
    est.v_WR = s.map.state().mean(s.robot.block()).segment<3>(models::ConstantVelocityIndex::kV);
    est.cov = s.map.state().cov(s.robot.block()).topLeftCorner<6, 6>();
    result.estimate.poses.push_back(est);
  }
  PointDemoResult& result;
};

}  // namespace

PointDemoResult run_point_demo(const PointDemoOptions& o, const std::function<void(int, int)>& on_frame) {
  o.validate();
  Rng rng(o.seed);
  const std::vector<Eigen::Vector3d> points = sim::points_on_box_faces(o.room_min, o.room_max, o.n_points, rng);
  const Eigen::Vector3d centre = 0.5 * (o.room_min + o.room_max);
  const auto trajectory = sim::make_handheld(o.seed, centre, o.duration_s);
  const models::CameraIntrinsics intr = euroc_cam0_intrinsics();
  const math::Pose T_RS = euroc_cam0_T_RS();
  const models::PinholeCamera camera(intr);

  // The SLAM system, built as every other: one map, one constant-velocity robot with one camera whose data manager
  // knows the association of the simulated points.
  ImageSlamOptions so;
  so.seed = o.seed;
  so.robot = "constant_velocity";
  so.data_manager = "known_association";
  so.state_capacity = o.state_capacity;
  so.initial_velocity_std = o.initial_velocity_std;
  so.motion = o.motion;
  so.association = o.association;
  so.map = o.map;
  so.health.enabled = false;  // the demo judges itself against its simulated truth (and has no recovery to show)
  // Gauge: the first robot pose defines W (zero covariance, true initial pose); v, ω: zero mean, documented std.
  const sim::KinematicState s0 = trajectory->at(trajectory->t_begin());
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(13);
  x0.head<3>() = s0.p_WR;
  x0.segment<4>(3) = math::quat_to_wxyz(s0.q_WR);
  Eigen::MatrixXd P0 = Eigen::MatrixXd::Zero(12, 12);
  P0.bottomRightCorner<6, 6>() = o.initial_velocity_std * o.initial_velocity_std * Eigen::MatrixXd::Identity(6, 6);
  const io::Rig rig = demo_rig();
  BuiltSystem built = build_system(BuildContext{so, rig, "points demo", x0, P0});
  slam::System& system = *built.system;

  PointDemoResult result;
  DemoCollector collector(result);
  system.add_observer(collector);
  const int n_frames = static_cast<int>(std::floor(o.duration_s * o.rate_hz)) + 1;
  result.frames.reserve(static_cast<size_t>(n_frames));
  const int sensor_id = built.cameras.front().sensor->id();
  const double margin = o.association.margin_px;
  for (int k = 0; k < n_frames; ++k) {
    const TimeNs t = trajectory->t_begin() + from_seconds(k / o.rate_hz);
    const sim::KinematicState s = trajectory->at(t);
    const math::Pose T_WR{s.q_WR, s.p_WR};
    const math::Pose T_WS = T_WR * T_RS;
    auto raw = system.spare<strategies::RawPoints>();
    raw->t = t;
    raw->sensor_id = sensor_id;
    raw->points.clear();
    for (size_t i = 0; i < points.size(); ++i) {
      Eigen::Vector2d z;
      if (!camera.project(T_WS.inverse_transform(points[i]), z)) continue;
      z += Eigen::Vector2d(randn(rng), randn(rng)) * o.sigma_px;
      if (!camera.in_image(z, margin)) continue;
      raw->points.push_back({static_cast<int>(i), z});
    }
    system.feed(std::move(raw));
    StampedPose gt = stamped(t, T_WR);
    gt.v_WR = s.v_WR;
    result.groundtruth.poses.push_back(gt);
    if (on_frame) on_frame(k + 1, n_frames);
  }
  const slam::Map& map = system.map();
  result.landmarks_final = static_cast<int>(map.landmarks().size());
  for (const auto& l : map.landmarks()) {
    result.landmarks_created = std::max(result.landmarks_created, l->id() + 1);
    if (l->type() == slam::LandmarkType::EuclideanPoint) ++result.euclidean_final;
  }
  result.estimate.source = "rtslam demo estimate";
  result.groundtruth.source = "rtslam demo ground truth";
  return result;
}

}  // namespace rtslam::pipeline
