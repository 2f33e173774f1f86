#include "rtslam/pipeline/image_slam.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <variant>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/core/ring_buffer.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/pipeline/config_common.hpp"
#include "rtslam/sim/simulation.hpp"
#include "rtslam/pipeline/known_landmarks.hpp"
#include "rtslam/pipeline/builder.hpp"
#include "rtslam/pipeline/starters.hpp"
#include "rtslam/strategies/vi_init.hpp"
#include "rtslam/slam/health.hpp"
#include "rtslam/slam/odometry_robot.hpp"
#include "rtslam/slam/system.hpp"
#include "rtslam/viz/overlay.hpp"
#include "rtslam/viz/report.hpp"

namespace rtslam::pipeline {


void ImageSlamOptions::validate() const {
  const std::string where = "slam";
  require_bound(initial_velocity_std > 0.0, where, "initial_velocity_std", initial_velocity_std, "> 0");
  require_bound(state_capacity >= 100, where, "state_capacity", state_capacity, ">= 100");
  require_bound(state_capacity >= map.map_size, where, "state_capacity", state_capacity, ">= map_manager/map_size");
  require_bound(max_frames >= 0, where, "max_frames", max_frames, ">= 0");
  require_bound(camera >= 0, where, "camera", camera, ">= 0");
  validate_slam_bounds(*this);
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    require_bound(cameras[i] >= 0 && cameras[i] <= io::DatasetOptions::kMaxCameraIndex, where, "cameras", cameras[i],
                  fmt::format("in [0, {}]", io::DatasetOptions::kMaxCameraIndex));
    for (std::size_t j = 0; j < i; ++j) {
      if (cameras[j] == cameras[i]) throw ConfigError(fmt::format("slam/cameras lists camera {} twice", cameras[i]));
    }
  }
  require_bound(rate_hz >= 0.0, where, "rate_hz", rate_hz, ">= 0");
  require_bound(sim_duration_s >= 0.0, "simulation", "duration", sim_duration_s, ">= 0");
  if (sim_camera_time_offset_ms) {
    require_bound(std::abs(*sim_camera_time_offset_ms) <= 500.0, "simulation", "camera_time_offset_ms",
                  *sim_camera_time_offset_ms, "within ±500 ms");
  }
  if (sim_preset.empty()) throw ConfigError("simulation/preset must not be empty");
  require_bound(overlay_frame >= -1, where, "overlay_frame", overlay_frame, ">= -1");
  if (overlay_frame >= 0 && overlay_path.empty()) throw ConfigError("slam/overlay_frame needs slam/overlay_path");
  if (consistency != "none" && consistency != "oc" && consistency != "fej") {
    throw ConfigError(fmt::format("slam/consistency = '{}' must be none, oc or fej", consistency));
  }
  if (consistency != "none" && !known_landmarks.empty()) {
    throw ConfigError("slam/consistency = oc or fej needs the first robot pose as the gauge: it cannot be combined "
                      "with slam/known_landmarks (whose points define the world frame)");
  }
  imu.validate();
  if (known_landmarks_convention != "scenelib" && known_landmarks_convention != "robot") {
    throw ConfigError(fmt::format("slam/known_landmarks_convention = '{}' must be robot or scenelib",
                                  known_landmarks_convention));
  }
  motion.validate();
  odometry.validate();
  if (odometry_rescale != "auto" && odometry_rescale != "on" && odometry_rescale != "off") {
    throw ConfigError(fmt::format("odometry/rescale = '{}' must be auto, on or off", odometry_rescale));
  }
  odometry_scale.validate();
  search.validate();
  map.validate();
  health.validate();
  zero_velocity.validate();
  planar_motion.validate();
  if (planar_motion.enabled && consistency == "oc") {
    throw ConfigError("planar_motion with slam/consistency = oc: the constrained filter keeps the world's tilt and "
                      "height unobservable, which the plane measures; use consistency none or fej");
  }
  if (zero_velocity.enabled && robot == "odometry") {
    throw ConfigError("zero_velocity with slam/robot = odometry: the odometry robot's state [p q] has no velocity to "
                      "set to 0 (the odometry itself says when it stands still); turn zero_velocity off");
  }
  time_offset.validate();
  if (time_offset.estimate && robot != "inertial") {
    throw ConfigError(fmt::format("camera/time_offset/estimate needs slam/robot = inertial (a camera's time offset is "
                                  "relative to the IMU clock), not '{}'", robot));
  }
  position_sensor.validate("position_sensor");
  pose_sensor.validate("pose_sensor");
  for (const auto& [name, a] : {std::pair<const char*, const strategies::AbsoluteSensorOptions*>{"position_sensor",
                                                                                              &position_sensor},
                                {"pose_sensor", &pose_sensor}}) {
    if (!a->enabled) continue;
    if (!known_landmarks.empty() && a->world == "align") {
      throw ConfigError(fmt::format("{}/world = align cannot move a map whose frame slam/known_landmarks defines",
                                    name));
    }
    if (planar_motion.enabled && a->world == "align") {
      throw ConfigError(fmt::format("planar_motion with {}/world = align: the alignment moves the world frame the "
                                    "plane is held in; give the frame (world = start) or turn one off", name));
    }
  }
  if (position_sensor.enabled && position_sensor.world == "align" && robot != "inertial") {
    throw ConfigError("position_sensor/world = align needs slam/robot = inertial (gravity gives roll and pitch, the "
                      "fixes yaw and translation); with another robot give the frame: world = start");
  }
}

std::vector<int> ImageSlamOptions::camera_indices() const {
  return cameras.empty() ? std::vector<int>{camera} : cameras;
}

ImageSlamOptions ImageSlamOptions::on_selected_cameras() const {
  ImageSlamOptions o = *this;
  o.camera = 0;
  o.cameras.clear();
  if (cameras.size() > 1) {
    for (std::size_t i = 0; i < cameras.size(); ++i) o.cameras.push_back(static_cast<int>(i));
  }
  return o;
}

void apply_image_slam_config(const YAML::Node& root, const std::string& where, ImageSlamOptions& o) {
  YamlMap top(root, where);
  if (top.has("demo") && !top.has("slam")) {  // e.g. a points-demo run's config.yaml
    throw ConfigError(fmt::format("{}: a configuration of the points demo (key 'demo'): run it with rtslam run "
                                  "--points-demo --config {}",
                                  where, where));
  }
  {
    YamlMap s = top.child("slam");
    s.get("seed", o.seed);
    s.get("robot", o.robot);
    s.get("data_manager", o.data_manager);
    s.get("map_manager", o.map_manager);
    s.get("consistency", o.consistency);
    s.get("initial_velocity_std", o.initial_velocity_std);
    s.get("state_capacity", o.state_capacity);
    s.get("max_frames", o.max_frames);
    s.get("camera", o.camera);
    s.get("cameras", o.cameras);
    s.get("rate_hz", o.rate_hz);
    s.get("known_landmarks", o.known_landmarks);
    s.get("known_landmarks_convention", o.known_landmarks_convention);
    s.get("overlay_frame", o.overlay_frame);
    s.get("overlay_path", o.overlay_path);
    s.finish();
  }
  read_motion(top.child("motion"), o.motion);
  read_odometry(top.child("odometry"), o.odometry, o.odometry_rescale, o.odometry_scale);
  read_inertial(top.child("imu"), o.imu);
  if (top.has("search")) {
    YamlMap a = top.child("search");
    o.search = strategies::ActiveSearchOptions::from_yaml(a);
  }
  read_map_policy(top.child("map_manager"), o.map);
  slam::read_health(top.child("health"), o.health);
  strategies::read_zero_velocity(top.child("zero_velocity"), o.zero_velocity);
  strategies::read_planar_motion(top.child("planar_motion"), o.planar_motion);
  if (top.has("position_sensor")) strategies::read_absolute_sensor(top.child("position_sensor"), o.position_sensor, false);
  if (top.has("pose_sensor")) strategies::read_absolute_sensor(top.child("pose_sensor"), o.pose_sensor, true);
  {
    YamlMap c = top.child("camera");
    slam::read_time_offset(c.child("time_offset"), o.time_offset);
    c.finish();
  }
  {
    YamlMap s = top.child("simulation");
    s.get("preset", o.sim_preset);
    s.get("duration", o.sim_duration_s);
    if (s.has("camera_time_offset_ms")) o.sim_camera_time_offset_ms = s.require<double>("camera_time_offset_ms");
    s.finish();
  }
  top.finish();
  try {
    o.validate();
    Registry::builtin().check(o);
  } catch (const ConfigError& e) {
    throw ConfigError(fmt::format("{}: {}", where, e.what()));
  }
}

ImageSlamOptions load_image_slam_config(const std::string& path) {
  ImageSlamOptions o;
  apply_image_slam_config(load_yaml_file(path), path, o);
  return o;
}

YAML::Node to_yaml(const ImageSlamOptions& o) {
  YAML::Node root;
  root["slam"]["seed"] = o.seed;
  root["slam"]["robot"] = o.robot;
  root["slam"]["data_manager"] = o.data_manager;
  root["slam"]["map_manager"] = o.map_manager;
  root["slam"]["consistency"] = o.consistency;
  root["slam"]["initial_velocity_std"] = o.initial_velocity_std;
  root["slam"]["state_capacity"] = o.state_capacity;
  root["slam"]["max_frames"] = o.max_frames;
  root["slam"]["camera"] = o.camera;
  root["slam"]["cameras"] = o.cameras;
  root["slam"]["rate_hz"] = o.rate_hz;
  root["slam"]["known_landmarks"] = o.known_landmarks;
  root["slam"]["known_landmarks_convention"] = o.known_landmarks_convention;
  root["slam"]["overlay_frame"] = o.overlay_frame;
  root["slam"]["overlay_path"] = o.overlay_path;
  root["motion"] = motion_to_yaml(o.motion);
  root["odometry"] = odometry_to_yaml(o.odometry, o.odometry_rescale, o.odometry_scale);
  root["imu"] = inertial_to_yaml(o.imu);
  root["search"] = o.search.to_yaml();
  root["map_manager"] = map_policy_to_yaml(o.map);
  root["health"] = slam::health_to_yaml(o.health);
  root["zero_velocity"] = strategies::zero_velocity_to_yaml(o.zero_velocity);
  root["planar_motion"] = strategies::planar_motion_to_yaml(o.planar_motion);
  root["camera"]["time_offset"] = slam::time_offset_to_yaml(o.time_offset);
  root["position_sensor"] = strategies::absolute_sensor_to_yaml(o.position_sensor, false);
  root["pose_sensor"] = strategies::absolute_sensor_to_yaml(o.pose_sensor, true);
  root["simulation"]["preset"] = o.sim_preset;
  root["simulation"]["duration"] = o.sim_duration_s;
  if (o.sim_camera_time_offset_ms) root["simulation"]["camera_time_offset_ms"] = *o.sim_camera_time_offset_ms;
  return root;
}

models::CameraIntrinsics to_intrinsics(const io::CameraCalibration& cam) {
  // The io → models conversion lives with the simulator (which needs it too); a dataset's camera is validated here.
  models::CameraIntrinsics c = sim::to_intrinsics(cam);
  c.validate();
  return c;
}

io::Dataset make_sim_dataset(const ImageSlamOptions& o) {
  o.validate();
  sim::SimConfig sc = sim::SimConfig::load(o.sim_preset);
  sc.seed = o.seed;
  sc.trajectory_seed.reset();
  if (o.sim_duration_s > 0.0) sc.duration_s = o.sim_duration_s;
  if (o.sim_camera_time_offset_ms) sc.camera_time_offset_s = 1e-3 * *o.sim_camera_time_offset_ms;
  // The simulator renders camera 0, and camera 1 (the right camera of its stereo rig) when the options use it.
  for (const int c : o.camera_indices()) {
    if (c > 1) throw ConfigError(fmt::format("slam/cameras: the simulator has cameras 0 and 1, not {}", c));
    if (c == 1) sc.stereo = true;
  }
  // The odometry robot is driven by the simulator's odometry (its own noise keys, or the defaults).
  if (o.robot == "odometry") sc.odometry.enabled = true;
  sc.validate();
  return sim::Simulation::create(sc)->make_dataset();
}

namespace {

// slam/overlay_frame: the PNG of one frame, drawn by viz (the same drawing as `rtslam run --overlays`).
void write_overlay(const std::string& path, const ImageSlamFrame& frame, double n_sigma) {
  viz::OverlayOptions oo;
  oo.n_sigma = n_sigma;
  const cv::Mat img = viz::draw_overlay(viz::make_report(frame, *frame.image, frame.stats, frame.grid), oo);
  bool ok = false;
  try {
    ok = io::codecs::imwrite(path, img);
  } catch (const cv::Exception& e) {
    throw IoError(fmt::format("{}: cannot write the overlay image ({})", path, e.what()));
  }
  if (!ok) throw IoError(fmt::format("{}: cannot write the overlay image", path));
}

}  // namespace

// The session: the built System, the stream it is fed from, and the result collected by observing its steps.
struct ImageSlam::Impl final : slam::Observer {
  Impl(io::Source& src, const io::Rig& r, std::string n, const ImageSlamOptions& opt)
      : source(src), rig(r), name(std::move(n)), o(opt), built(build_system(BuildContext{o, rig, name})) {
    inertial = o.robot == "inertial";
    if (inertial) {
      t_d = o.imu.time_offset_s ? from_seconds(*o.imu.time_offset_s) : rig.t_d;
      if (o.imu.gyro_saturation) gyro_full_scale = *o.imu.gyro_saturation;
      else if (rig.imu && rig.imu->gyro_saturation) gyro_full_scale = *rig.imu->gyro_saturation;
      if (o.imu.accel_saturation) accel_full_scale = *o.imu.accel_saturation;
      else if (rig.imu && rig.imu->accel_saturation) accel_full_scale = *rig.imu->accel_saturation;
      imu_range = io::ImuRange::from_full_scale(
          gyro_full_scale > 0.0 ? std::optional<double>(gyro_full_scale) : std::nullopt,
          accel_full_scale > 0.0 ? std::optional<double>(accel_full_scale) : std::nullopt);
    }
    camera = &built.cameras.front();
    by_rig_index.assign(rig.cameras.size(), nullptr);
    for (const BuiltCamera& c : built.cameras) by_rig_index[static_cast<std::size_t>(c.rig_index)] = &c;
    held.reserve(built.cameras.size());
    held_paths.resize(built.cameras.size());
    result.inertial = inertial;
    result.cameras = static_cast<int>(built.cameras.size());
    const auto total = source.image_count();
    n_total = total ? static_cast<int>(*total / built.cameras.size()) : 0;  // progress counts the first camera's
    // One entry per image: reserved when the count is known, so that the frame loop does not reallocate them.
    result.frames.reserve(static_cast<std::size_t>(n_total));
    result.estimate.poses.reserve(static_cast<std::size_t>(n_total));
    built.system->add_observer(*this);
  }

  // Several cameras: the images of one time are one frame of the result (statistics summed, the pose after the
  // last of them) and one call of the observer.
  static void merge(slam::FrameStats& a, const slam::FrameStats& b) {
    a.landmarks_in_map = b.landmarks_in_map;
    a.visible += b.visible;
    a.searched += b.searched;
    a.matched += b.matched;
    a.updated += b.updated;
    a.initialized += b.initialized;
    a.ransac_inliers += b.ransac_inliers;
    a.ransac_hypotheses += b.ransac_hypotheses;
    a.ransac_max += b.ransac_max;
    a.fallback += b.fallback;
    a.reparametrized += b.reparametrized;
    a.removed += b.removed;
    a.evicted += b.evicted;
    a.refused += b.refused;
    a.absolute_updates += b.absolute_updates;
    a.absolute_rejected += b.absolute_rejected;
    a.nis += b.nis;
    a.nis_count += b.nis_count;
    a.health = std::max(a.health, b.health);
    a.reset = a.reset || b.reset;
    a.zero_velocity = a.zero_velocity || b.zero_velocity;
    a.budget_hit = a.budget_hit || b.budget_hit;
    a.budget_skipped += b.budget_skipped;
    a.time_search_ms += b.time_search_ms;
    a.time_predict_ms += b.time_predict_ms;
    a.time_match_ms += b.time_match_ms;
    a.time_ransac_ms += b.time_ransac_ms;
    a.time_update_ms += b.time_update_ms;
    a.time_init_ms += b.time_init_ms;
    a.time_map_ms += b.time_map_ms;
    a.time_total_ms += b.time_total_ms;
  }

  void on_step(const slam::StepReport& s) override {
    if (!s.stats.landmark_frame) {  // an absolute fix: no pose of its own, counted in the next frame
      fixes_since_frame.absolute_updates += s.stats.absolute_updates;
      fixes_since_frame.absolute_rejected += s.stats.absolute_rejected;
      fixes_since_frame.refused += s.stats.refused;
      return;
    }
    const bool same_time = !result.frames.empty() && result.frames.back().t == s.raw.t;
    if (same_time) merge(result.frames.back(), s.stats);
    else result.frames.push_back(s.stats);
    take_fixes(result.frames.back());
    const slam::FrameStats& fs = result.frames.back();
    StampedPose& est = same_time ? result.estimate.poses.back() : result.estimate.poses.emplace_back();
    est.t = s.robot.time();  // the datum's time in the IMU clock, with the estimated time offset when there is one
    const math::Pose T_WR = s.robot.pose();
    est.p_WR = T_WR.p;
    est.q_WR = T_WR.q;
    const auto x = s.map.state().mean(s.robot.block());
    if (inertial) {
      using I = models::InertialIndex;
      est.v_WR = x.segment<3>(I::kV);
      est.accel_bias = x.segment<3>(I::kAb);
      est.gyro_bias = x.segment<3>(I::kWb);
    } else if (x.size() == models::ConstantVelocityIndex::kAmbientSize) {
      est.v_WR = x.segment<3>(models::ConstantVelocityIndex::kV);
    }
    est.cov = s.map.state().cov(s.robot.block()).topLeftCorner<6, 6>();
    const auto* image = dynamic_cast<const MatImage*>(&s.raw);
    if (image != nullptr && (!image->closes_time || (observed_t && *observed_t == s.raw.t))) return;
    observed_t = s.raw.t;
    const int index = static_cast<int>(result.frames.size()) - 1;
    const bool overlay = index == o.overlay_frame;
    const auto* dm = dynamic_cast<const strategies::ActiveSearchDataManager*>(s.sensor.data_manager());
    if ((observer || overlay) && image != nullptr && dm != nullptr) {
      const ImageSlamFrame f{index, s.raw.t, &s.map, &dm->last_frame(), &image->mat, &fs, &dm->grid(), &est};
      if (overlay) write_overlay(o.overlay_path, f, o.search.n_sigma);
      if (observer) observer(f);
    }
  }

  // The absolute fixes since the last frame go into the next one (its row of frames.csv is written after it).
  void take_fixes(slam::FrameStats& f) {
    f.absolute_updates += fixes_since_frame.absolute_updates;
    f.absolute_rejected += fixes_since_frame.absolute_rejected;
    f.refused += fixes_since_frame.refused;
    fixes_since_frame = {};
  }

  void feed_image(std::unique_ptr<MatImage> d, const std::string& path) {
    try {
      built.system->feed(std::move(d));
    } catch (const DataError& e) {
      throw DataError(fmt::format("{}: {}", path, e.what()));
    }
  }
  // The held images of one time, the last one closing it.
  void flush_held() {
    for (std::size_t i = 0; i < held.size(); ++i) {
      held[i]->closes_time = i + 1 == held.size();
      feed_image(std::move(held[i]), held_paths[i]);
    }
    held.clear();
  }

  // One measurement of the stream into the System; false at its end.
  bool feed_next() {
    auto m = source.next();
    if (!m) {
      flush_held();
      return false;
    }
    slam::System& system = *built.system;
    if (const auto* imu = std::get_if<io::ImuSample>(&*m)) {
      flush_held();
      if (!inertial) return true;
      ++result.imu_samples;
      if (gyro_full_scale > 0.0 && imu->gyro.cwiseAbs().maxCoeff() >= gyro_full_scale) ++result.imu_gyro_saturated;
      if (accel_full_scale > 0.0 && imu->accel.cwiseAbs().maxCoeff() >= accel_full_scale) ++result.imu_accel_saturated;
      // The readers apply the calibration's range; the imu/*_saturation keys may narrow it. A sample beyond the
      // sensor's range is counted above and never integrated.
      if (const std::string beyond = io::imu_range_problem(*imu, imu_range); !beyond.empty()) {
        logger("slam")->warn("t = {:.3f} s: IMU sample not integrated: {}", to_seconds(imu->t), beyond);
        return true;
      }
      last_imu_t = imu->t;
      auto d = system.spare<slam::ImuData>();
      d->t = imu->t;
      d->sensor_id = built.input_id;
      d->m = models::ImuMeasurement{imu->accel, imu->gyro};
      system.feed(std::move(d));
      return true;
    }
    if (const auto* odo = std::get_if<io::OdometrySample>(&*m)) {
      flush_held();
      if (dynamic_cast<const slam::OdometryRobot*>(built.robot) == nullptr) return true;
      auto d = system.spare<slam::OdometryData>();
      d->t = odo->t;
      d->t_from = odo->t_from;
      d->sensor_id = built.input_id;
      d->dp = odo->dp;
      d->dtheta = odo->dtheta;
      system.feed(std::move(d));
      return true;
    }
    if (const auto* fix = std::get_if<io::PositionSample>(&*m)) {
      flush_held();
      if (built.position_sensor == nullptr) return true;
      auto d = system.spare<slam::PositionData>();
      d->t = fix->t;
      d->sensor_id = built.position_sensor->id();
      d->p_WA = fix->p;
      d->has_cov = false;
      system.feed(std::move(d));
      return true;
    }
    if (const auto* fix = std::get_if<io::PoseSample>(&*m)) {
      flush_held();
      if (built.pose_sensor == nullptr) return true;
      auto d = system.spare<slam::PoseData>();
      d->t = fix->t;
      d->sensor_id = built.pose_sensor->id();
      d->T_WM = math::Pose{fix->q, fix->p};
      d->has_cov = false;
      system.feed(std::move(d));
      return true;
    }
    auto* frame = std::get_if<io::ImageFrame>(&*m);
    if (frame == nullptr) return true;
    const BuiltCamera* cam = frame->camera >= 0 && static_cast<std::size_t>(frame->camera) < by_rig_index.size()
                                 ? by_rig_index[static_cast<std::size_t>(frame->camera)]
                                 : nullptr;
    if (cam == nullptr) return true;
    if (frame->image.type() != CV_8UC1) throw DataError(fmt::format("{}: image is not 8-bit grey", frame->path));
    auto d = system.spare<MatImage>();
    const std::optional<TimeNs> t_imu = add_checked(frame->t, t_d);
    if (!t_imu) {
      throw DataError(fmt::format("{}: its time {} s plus the camera-IMU time offset t_d {} s lies beyond the int64 "
                                  "nanosecond range (check t_d / t_d_ns / imu/time_offset)", frame->path,
                                  to_seconds(frame->t), to_seconds(t_d)));
    }
    if (cam == camera) {
      if (consumed++ == 0) first_image_t = *t_imu;
      last_image_t = *t_imu;
    }
    d->set(*t_imu, cam->sensor->id(), std::move(frame->image));
    if (built.cameras.size() == 1) {
      feed_image(std::move(d), frame->path);
    } else {
      // Several cameras: an image waits for the others of its time (they come together in the stream).
      if (!held.empty() && held.front()->t != d->t) flush_held();
      held_paths[held.size()] = frame->path;
      held.push_back(std::move(d));
      if (held.size() == built.cameras.size()) flush_held();
    }
    if (progress && cam == camera) progress(consumed, n_total);
    return true;
  }

  ImageSlamResult finish() {
    if (!result.frames.empty()) take_fixes(result.frames.back());  // fixes after the last frame
    const slam::System& system = *built.system;
    const slam::Map& map = *built.map;
    const slam::Robot& robot = *built.robot;
    const slam::System::RobotCounts& counts = system.counts(0);
    if (!counts.started) {
      const std::string& cam_name = camera->sensor->name();
      if (system.pending() > 0) {  // images waiting for the robot's inputs (IMU or odometry) to cover them
        if (stopped) {
          throw DataError(fmt::format("dataset '{}': the run was stopped before the robot started ({} image(s) from "
                                      "{:.3f} s still waiting for its {} data)",
                                      name, system.pending(), to_seconds(system.first_pending().value_or(0)),
                                      inertial ? "IMU" : "odometry"));
        }
        if (inertial) {
          throw DataError(fmt::format("dataset '{}': the IMU stream ends before the images (last IMU sample at {:.3f} "
                                      "s, {} image(s) from {:.3f} s never covered): the filter could not start",
                                      name, last_imu_t ? to_seconds(*last_imu_t) : 0.0, system.pending(),
                                      to_seconds(system.first_pending().value_or(0))));
        }
        throw DataError(fmt::format("dataset '{}': the robot's odometry ends before the images ({} image(s) from "
                                    "{:.3f} s never covered): the filter could not start",
                                    name, system.pending(), to_seconds(system.first_pending().value_or(0))));
      }
      if (consumed == 0 && source.stats().live_images_before_imu > 0) {
        throw DataError(fmt::format("dataset '{}': no IMU sample came ({} camera frame(s) dropped waiting for the "
                                    "first one): is the IMU stream written, and on its topic or path?",
                                    name, source.stats().live_images_before_imu));
      }
      if (consumed == 0) {
        throw DataError(fmt::format("dataset '{}' has no image of camera {} (in the part of it read: see --start-at, "
                                    "--stop-after)",
                                    name, cam_name));
      }
      const std::string waiting = built.starter->waiting_for();
      throw DataError(fmt::format("dataset '{}': the robot did not start over its {} image(s) of camera {} ({:.3f} to "
                                  "{:.3f} s{}){}{}",
                                  name, consumed, cam_name, to_seconds(first_image_t), to_seconds(last_image_t),
                                  inertial ? ", the IMU's clock" : "",
                                  stopped ? " before the run was stopped" : "",
                                  waiting.empty() ? "" : ": it still needed " + waiting));
    }
    result.images_not_covered = stopped ? 0 : static_cast<int>(system.pending());
    if (result.images_not_covered > 0) {
      logger("slam")->warn("{} image(s) after the last IMU sample were not processed", result.images_not_covered);
    }
    result.images_before_start = built.starter->skipped();
    if (const auto* ps = dynamic_cast<const PoseStarter*>(built.starter)) result.known_landmarks = ps->known_landmarks_added();
    if (inertial) result.inertial_start = counts.start;
    result.frames_lost = counts.frames_lost;
    result.frames_diverged = counts.frames_diverged;
    result.resets = counts.resets;
    result.final_health = counts.final_health;
    if (const auto* odo_robot = dynamic_cast<const slam::OdometryRobot*>(&robot)) {
      result.odometry_rescale = odo_robot->keeps_scale();
      result.odometry_rescales = odo_robot->rescales();
      result.odometry_rescale_product = odo_robot->rescale_product();
    }
    result.frame_gaps = system.health(0).frame_gaps();
    const Eigen::VectorXd& mean = map.state().mean_vector();
    if (const auto* imu_robot = dynamic_cast<const slam::InertialRobot*>(&robot)) {
      using I = models::InertialIndex;
      result.imu_samples_integrated = imu_robot->samples_integrated();
      const auto x = map.state().mean(robot.block());
      result.gravity_W = x.segment<3>(I::kG);
      result.accel_bias = x.segment<3>(I::kAb);
      result.gyro_bias = x.segment<3>(I::kWb);
    }
    const slam::Sensor& sensor = *camera->sensor;
    result.T_RS_calibration = camera->T_RS;
    result.T_RS_estimate = camera->T_RS;
    if (sensor.block() != filter::kNoBlock) {
      result.extrinsics_estimated = true;
      result.T_RS_estimate = sensor.T_RS(mean);
      result.T_RS_std = map.state().cov(sensor.block()).diagonal().cwiseSqrt();
    }
    result.time_offset_stamped_s = to_seconds(t_d);
    result.time_offset_estimate_s = to_seconds(t_d);
    if (sensor.time_block() != filter::kNoBlock) {
      result.time_offset_estimated = true;
      result.time_offset_estimate_s += sensor.time_offset(mean);
      result.time_offset_std_s = std::sqrt(map.state().cov(sensor.time_block())(0, 0));
    }
    const Eigen::Vector3d p_WS = sensor.pose_in_world(mean).p;
    result.landmarks_created = map.landmarks_added();
    for (const auto& l : map.landmarks()) {
      if (l->type() == slam::LandmarkType::EuclideanPoint) ++result.euclidean_final;
      const Eigen::Vector3d p = l->position(mean);
      result.landmark_ids.push_back(l->id());
      result.landmark_positions.push_back(p);
      result.landmark_euclidean.push_back(l->type() == slam::LandmarkType::EuclideanPoint ? 1 : 0);
      Eigen::Matrix3d cov;
      const auto P = map.state().cov(l->block());
      if (l->type() == slam::LandmarkType::EuclideanPoint) {
        cov = P;
      } else {  // AHP [p0 m ρ]: p = p0 + m/ρ
        const auto L = map.state().mean(l->block());
        const double rho = L[6];
        Eigen::Matrix<double, 3, 7> J;
        J << Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity() / rho, -L.segment<3>(3) / (rho * rho);
        cov = J * P * J.transpose();
      }
      result.landmark_covariances.push_back(cov);
      result.landmark_depths.push_back((p - p_WS).norm());
    }
    result.landmarks_final = static_cast<int>(map.landmarks().size());
    result.estimate.source = fmt::format("rtslam image SLAM on {}", name);
    return std::move(result);
  }

  io::Source& source;
  const io::Rig& rig;
  std::string name;
  ImageSlamOptions o;
  BuiltSystem built;
  const BuiltCamera* camera = nullptr;  // the first (reference) camera
  std::vector<const BuiltCamera*> by_rig_index;
  std::vector<std::unique_ptr<MatImage>> held;  // several cameras: images of one time not fed yet
  std::vector<std::string> held_paths;
  std::optional<TimeNs> observed_t;             // the time the observer last saw
  slam::FrameStats fixes_since_frame;           // absolute fixes since the last frame (their counters only)
  bool inertial = false;
  TimeNs t_d = 0;  // t_imu = t_cam + t_d
  double gyro_full_scale = 0.0, accel_full_scale = 0.0;  // 0: unknown
  io::ImuRange imu_range;
  std::optional<TimeNs> last_imu_t;
  ImageSlamResult result;
  std::function<void(const ImageSlamFrame&)> observer;
  std::function<void(int, int)> progress;
  int n_total = 0, consumed = 0;
  TimeNs first_image_t = 0, last_image_t = 0;  // of the images of `camera` read (the IMU's clock: + t_d)
  bool ended = false, stopped = false;
};

ImageSlam::ImageSlam(io::Source& source, const io::Rig& rig, std::string name, const ImageSlamOptions& options)
    : impl_(std::make_unique<Impl>(source, rig, std::move(name), options)) {
  // The overlay PNG's encoder: loaded now (~150 ms, and a missing plugin an error before the run), not mid-run.
  if (options.overlay_frame >= 0) io::codecs::load_plugin();
}
ImageSlam::~ImageSlam() = default;

void ImageSlam::set_observer(std::function<void(const ImageSlamFrame&)> observer) {
  impl_->observer = std::move(observer);
}
void ImageSlam::set_progress(std::function<void(int, int)> progress) { impl_->progress = std::move(progress); }
slam::System& ImageSlam::system() { return *impl_->built.system; }
const ImageSlamResult& ImageSlam::result() const { return impl_->result; }

bool ImageSlam::step(const std::atomic<bool>* stop) {
  Impl& s = *impl_;
  const long before = s.built.system->steps();
  while (!s.ended) {
    if ((stop != nullptr && stop->load()) || s.built.system->finished()) {
      s.stopped = true;
      s.ended = true;
    } else if (!s.feed_next()) {
      s.ended = true;
    } else if (s.built.system->steps() > before) {
      return true;
    }
  }
  return s.built.system->steps() > before;
}

ImageSlamResult ImageSlam::finish() { return impl_->finish(); }

ImageSlamResult run_image_slam(io::Source& source, const io::Rig& rig, const std::string& name,
                               const ImageSlamOptions& o, const std::function<void(int, int)>& on_frame,
                               const std::function<void(const ImageSlamFrame&)>& observer,
                               const std::atomic<bool>* stop) {
  ImageSlam run(source, rig, name, o);
  run.set_progress(on_frame);
  run.set_observer(observer);
  while (run.step(stop)) {
  }
  return run.finish();
}

ImageSlamResult run_image_slam(io::Dataset& ds, const ImageSlamOptions& o,
                               const std::function<void(int, int)>& on_frame,
                               const std::function<void(const ImageSlamFrame&)>& observer,
                               const std::atomic<bool>* stop) {
  if (!ds.source) throw ConfigError(fmt::format("dataset '{}' has no measurement source", ds.name));
  return run_image_slam(*ds.source, ds.rig, ds.name, o, on_frame, observer, stop);
}

std::string never_tracked(const ImageSlamResult& result, int min_frames) {
  int camera_frames = 0;
  for (const slam::FrameStats& f : result.frames) {
    if (!f.landmark_frame) continue;
    if (f.updated > 0) return {};
    ++camera_frames;
  }
  if (camera_frames < min_frames) return {};
  return fmt::format("no landmark was matched and corrected in any of the {} camera frames: the estimate is the "
                     "robot's prediction alone, not SLAM (check the images, the calibration and search/zncc)",
                     camera_frames);
}

}  // namespace rtslam::pipeline
