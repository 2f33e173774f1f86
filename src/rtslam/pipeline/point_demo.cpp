#include "rtslam/pipeline/point_demo.hpp"

#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/filter/state.hpp"
#include "rtslam/sim/trajectory.hpp"
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

// Points spread uniformly over the room's six faces (by area).
std::vector<Eigen::Vector3d> make_room_points(const PointDemoOptions& o, Rng& rng) {
  const Eigen::Vector3d lo = o.room_min;
  const Eigen::Vector3d hi = o.room_max;
  const Eigen::Vector3d size = hi - lo;
  const double areas[3] = {size.y() * size.z(), size.x() * size.z(), size.x() * size.y()};  // faces ⟂ x, y, z
  const double total = 2.0 * (areas[0] + areas[1] + areas[2]);
  std::vector<Eigen::Vector3d> pts;
  pts.reserve(static_cast<size_t>(o.n_points));
  for (int i = 0; i < o.n_points; ++i) {
    double u = randu(rng, 0.0, total);
    int axis = 0;
    while (axis < 2 && u >= 2.0 * areas[axis]) u -= 2.0 * areas[axis++];
    Eigen::Vector3d p(randu(rng, lo.x(), hi.x()), randu(rng, lo.y(), hi.y()), randu(rng, lo.z(), hi.z()));
    p[axis] = u < areas[axis] ? lo[axis] : hi[axis];
    pts.push_back(p);
  }
  return pts;
}

StampedPose stamped(TimeNs t, const math::Pose& T_WR) {
  StampedPose s;
  s.t = t;
  s.p_WR = T_WR.p;
  s.q_WR = T_WR.q;
  return s;
}

}  // namespace

PointDemoResult run_point_demo(const PointDemoOptions& o, const std::function<void(int, int)>& on_frame) {
  o.validate();
  Rng rng(o.seed);
  const std::vector<Eigen::Vector3d> points = make_room_points(o, rng);
  const Eigen::Vector3d centre = 0.5 * (o.room_min + o.room_max);
  const auto trajectory = sim::make_handheld(o.seed, centre, o.duration_s);
  const models::CameraIntrinsics intr = euroc_cam0_intrinsics();
  const math::Pose T_RS = euroc_cam0_T_RS();
  const models::PinholeCamera camera(intr);

  // The SLAM system: one map, one constant-velocity robot with one camera.
  slam::World world;
  filter::StateOptions so;
  so.tangent_capacity = o.state_capacity;
  slam::Map& map = world.add_map(so);
  auto map_manager = std::make_unique<strategies::PolicyMapManager>(o.map);
  const strategies::PolicyMapManager& mm = *map_manager;
  slam::System system(world, map, std::move(map_manager));

  const sim::KinematicState s0 = trajectory->at(trajectory->t_begin());
  auto robot = std::make_unique<slam::ConstantVelocityRobot>(o.motion);
  slam::Sensor& sensor = robot->add_sensor(std::make_unique<slam::PinholeSensor>("cam0", intr, T_RS));
  // Gauge: the first robot pose defines W (zero covariance, true initial pose); v, ω: zero mean, documented std.
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(13);
  x0.head<3>() = s0.p_WR;
  x0.segment<4>(3) = math::quat_to_wxyz(s0.q_WR);
  Eigen::MatrixXd P0 = Eigen::MatrixXd::Zero(12, 12);
  P0.bottomRightCorner<6, 6>() = o.initial_velocity_std * o.initial_velocity_std * Eigen::MatrixXd::Identity(6, 6);
  map.add_robot(std::move(robot), x0, P0, trajectory->t_begin());
  sensor.set_data_manager(std::make_unique<strategies::KnownAssociationDataManager>(
      o.association, mm, intr.width, intr.height, o.seed * 7919 + 1));

  PointDemoResult result;
  const int n_frames = static_cast<int>(std::floor(o.duration_s * o.rate_hz)) + 1;
  result.frames.reserve(static_cast<size_t>(n_frames));
  strategies::RawPoints raw;
  raw.sensor_id = sensor.id();
  const double margin = o.association.margin_px;
  for (int k = 0; k < n_frames; ++k) {
    const TimeNs t = trajectory->t_begin() + from_seconds(k / o.rate_hz);
    const sim::KinematicState s = trajectory->at(t);
    const math::Pose T_WR{s.q_WR, s.p_WR};
    const math::Pose T_WS = T_WR * T_RS;
    raw.t = t;
    raw.points.clear();
    for (size_t i = 0; i < points.size(); ++i) {
      Eigen::Vector2d z;
      if (!camera.project(T_WS.inverse_transform(points[i]), z)) continue;
      z += Eigen::Vector2d(randn(rng), randn(rng)) * o.sigma_px;
      if (!camera.in_image(z, margin)) continue;
      raw.points.push_back({static_cast<int>(i), z});
    }
    const slam::FrameStats stats = system.process(raw);
    result.frames.push_back(stats);
    StampedPose est = stamped(t, map.robots()[0]->pose());
    est.v_WR = map.state().mean(map.robots()[0]->block()).segment<3>(7);
    est.cov = map.state().cov(map.robots()[0]->block()).topLeftCorner<6, 6>();
    result.estimate.poses.push_back(est);
    StampedPose gt = stamped(t, T_WR);
    gt.v_WR = s.v_WR;
    result.groundtruth.poses.push_back(gt);
    if (on_frame) on_frame(k + 1, n_frames);
  }
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
