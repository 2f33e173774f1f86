#include "rtslam/pipeline/point_demo.hpp"

#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/filter/state.hpp"
#include "rtslam/pipeline/builder.hpp"
#include "rtslam/slam/system.hpp"

namespace rtslam::pipeline {

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

sim::PointSceneOptions PointDemoOptions::scene() const {
  sim::PointSceneOptions s;
  s.seed = seed;
  s.duration_s = duration_s;
  s.rate_hz = rate_hz;
  s.n_points = n_points;
  s.room_min = room_min;
  s.room_max = room_max;
  s.sigma_px = sigma_px;
  s.margin_px = association.margin_px;
  return s;
}

void PointDemoOptions::validate() const {
  const std::string w = "demo";
  scene().validate(w);
  require_bound(initial_velocity_std > 0.0 && initial_velocity_std <= 100.0, w, "initial_velocity_std",
                initial_velocity_std, "in (0, 100]");
  require_bound(state_capacity >= 100 && state_capacity <= filter::StateOptions::kMaxTangentCapacity, w,
                "state_capacity", state_capacity,
                fmt::format("in [100, {}] covariance rows", filter::StateOptions::kMaxTangentCapacity));
  motion.validate();
  association.validate();
  map.validate();
}

namespace {

// Collects the estimate and the statistics of each step.
struct DemoCollector final : slam::Observer {
  explicit DemoCollector(PointDemoResult& r) : result(r) {}
  void on_step(const slam::StepReport& s) override {
    result.frames.push_back(s.stats);
    const math::Pose T_WR = s.robot.pose();
    StampedPose est;
    est.t = s.raw.t;
    est.p_WR = T_WR.p;
    est.q_WR = T_WR.q;
    est.v_WR = s.map.state().mean(s.robot.block()).segment<3>(models::ConstantVelocityIndex::kV);
    est.cov = s.map.state().cov(s.robot.block()).topLeftCorner<6, 6>();
    result.estimate.poses.push_back(est);
  }
  PointDemoResult& result;
};

}  // namespace

PointDemoResult run_point_demo(const PointDemoOptions& o, sim::PointScene& scene,
                               const std::function<void(int, int)>& on_frame) {
  o.validate();

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
  so.health.enabled = false;  // the demo is scored against its simulated truth afterwards (and has no recovery to show)
  // Gauge: the scene's start pose defines W (zero covariance); v, ω: zero mean, documented std.
  const math::Pose start = scene.start_pose();
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(13);
  x0.head<3>() = start.p;
  x0.segment<4>(3) = math::quat_to_wxyz(start.q);
  Eigen::MatrixXd P0 = Eigen::MatrixXd::Zero(12, 12);
  P0.bottomRightCorner<6, 6>() = o.initial_velocity_std * o.initial_velocity_std * Eigen::MatrixXd::Identity(6, 6);
  io::Rig rig;
  rig.cameras.push_back(scene.camera());
  BuiltSystem built = build_system(BuildContext{so, rig, "points demo", x0, P0});
  slam::System& system = *built.system;

  PointDemoResult result;
  DemoCollector collector(result);
  system.add_observer(collector);
  const int n_frames = scene.frame_count();
  result.frames.reserve(static_cast<size_t>(n_frames));
  const int sensor_id = built.cameras.front().sensor->id();
  std::vector<sim::ScenePoint> measured;
  for (int k = 0; k < n_frames; ++k) {
    scene.measure(k, measured);
    auto raw = system.spare<strategies::RawPoints>();
    raw->t = scene.frame_time(k);
    raw->sensor_id = sensor_id;
    raw->points.clear();
    for (const sim::ScenePoint& m : measured) raw->points.push_back({m.id, m.z});
    system.feed(std::move(raw));
    if (on_frame) on_frame(k + 1, n_frames);
  }
  const slam::Map& map = system.map();
  result.landmarks_final = static_cast<int>(map.landmarks().size());
  result.landmarks_created = map.landmarks_added();
  for (const auto& l : map.landmarks()) {
    if (l->type() == slam::LandmarkType::EuclideanPoint) ++result.euclidean_final;
  }
  result.estimate.source = "rtslam demo estimate";
  return result;
}

}  // namespace rtslam::pipeline
