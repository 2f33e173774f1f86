#include "rtslam/pipeline/image_slam.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <variant>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/core/ring_buffer.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/pipeline/config_common.hpp"
#include "rtslam/sim/simulation.hpp"
#include "rtslam/pipeline/known_landmarks.hpp"
#include "rtslam/pipeline/vi_init.hpp"
#include "rtslam/slam/health.hpp"
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
  require_bound(rate_hz >= 0.0, where, "rate_hz", rate_hz, ">= 0");
  require_bound(sim_duration_s >= 0.0, "simulation", "duration", sim_duration_s, ">= 0");
  if (sim_preset.empty()) throw ConfigError("simulation/preset must not be empty");
  require_bound(overlay_frame >= -1, where, "overlay_frame", overlay_frame, ">= -1");
  if (overlay_frame >= 0 && overlay_path.empty()) throw ConfigError("slam/overlay_frame needs slam/overlay_path");
 if (robot != "constant_velocity" && robot != "inertial") {
    throw ConfigError(fmt::format("slam/robot = '{}' must be constant_velocity or inertial", robot));
  }
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
  search.validate();
  map.validate();
  health.validate();
}

void apply_image_slam_config(const YAML::Node& root, const std::string& where, ImageSlamOptions& o) {
  YamlMap top(root, where);
  {
    YamlMap s = top.child("slam");
    s.get("seed", o.seed);
    s.get("robot", o.robot);
    s.get("consistency", o.consistency);
    s.get("initial_velocity_std", o.initial_velocity_std);
    s.get("state_capacity", o.state_capacity);
    s.get("max_frames", o.max_frames);
    s.get("camera", o.camera);
    s.get("rate_hz", o.rate_hz);
    s.get("known_landmarks", o.known_landmarks);
    s.get("known_landmarks_convention", o.known_landmarks_convention);
    s.get("overlay_frame", o.overlay_frame);
    s.get("overlay_path", o.overlay_path);
    s.finish();
  }
  read_motion(top.child("motion"), o.motion);
  read_inertial(top.child("imu"), o.imu);
  if (top.has("search")) {
    YamlMap a = top.child("search");
    o.search = strategies::ActiveSearchOptions::from_yaml(a);
  }
  read_map_policy(top.child("map_manager"), o.map);
  slam::read_health(top.child("health"), o.health);
  {
    YamlMap s = top.child("simulation");
    s.get("preset", o.sim_preset);
    s.get("duration", o.sim_duration_s);
    s.finish();
  }
  top.finish();
  try {
    o.validate();
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
  root["slam"]["consistency"] = o.consistency;
  root["slam"]["initial_velocity_std"] = o.initial_velocity_std;
  root["slam"]["state_capacity"] = o.state_capacity;
  root["slam"]["max_frames"] = o.max_frames;
  root["slam"]["camera"] = o.camera;
  root["slam"]["rate_hz"] = o.rate_hz;
  root["slam"]["known_landmarks"] = o.known_landmarks;
  root["slam"]["known_landmarks_convention"] = o.known_landmarks_convention;
  root["slam"]["overlay_frame"] = o.overlay_frame;
  root["slam"]["overlay_path"] = o.overlay_path;
  root["motion"] = motion_to_yaml(o.motion);
  root["imu"] = inertial_to_yaml(o.imu);
  const auto& a = o.search;
  YAML::Node s = root["search"];
  s["sigma_px"] = a.sigma_px;
  s["second_order_depth"] = a.second_order_depth;
  s["n_sigma"] = a.n_sigma;
  s["max_updates"] = a.max_updates;
  s["max_updates_ransac"] = a.max_updates_ransac;
  s["ransac_ntries"] = a.ransac_ntries;
  s["ransac_low_innov_px"] = a.ransac_low_innov_px;
  s["gain_recomputations"] = a.gain_recomputations;
  s["iterations"] = a.iterations;
  s["iteration_tolerance"] = a.iteration_tolerance;
  s["max_inits"] = a.max_inits;
  s["max_search_size_px2"] = a.max_search_size_px2;
  s["margin_px"] = a.margin_px;
  s["init_patch_size"] = a.init_patch_size;
  s["d_min"] = a.prior.d_min;
  s["depth_prior"] = a.depth_prior;
  s["depth_prior_sigma_ratio"] = a.prior.sigma_ratio;
  s["scene_prior_min_points"] = a.scene_prior_min_points;
  s["grid"]["cells_x"] = a.grid.cells_x;
  s["grid"]["cells_y"] = a.grid.cells_y;
  s["grid"]["margin_px"] = a.grid.margin_px;
  const auto& h = a.harris;
  s["harris"]["window_size"] = h.window_size;
  s["harris"]["k"] = h.k;
  s["harris"]["response"] = h.response == vision::HarrisResponse::harris ? "harris" : "min_eigen";
  s["harris"]["harris_threshold"] = h.harris_threshold;
  s["harris"]["min_eigen_threshold"] = h.min_eigen_threshold;
  s["harris"]["edge_ratio"] = h.edge_ratio;
  s["harris"]["border_px"] = h.border_px;
  s["harris"]["subpixel"] = h.subpixel == vision::HarrisSubpixel::quadratic ? "quadratic" : "edge_lines";
  const auto& z = a.zncc;
  s["zncc"]["threshold"] = z.threshold;
  s["zncc"]["patch_size"] = z.patch_size;
  s["zncc"]["two_level"] = z.two_level;
  s["zncc"]["partial_correlation"] = z.partial_correlation;
  s["zncc"]["coarse_margin"] = z.coarse_margin;
  s["zncc"]["coarse_candidates_spread"] = z.coarse_candidates_spread;
  s["zncc"]["climb_radius"] = z.climb_radius;
  s["zncc"]["partial_step_rows"] = z.partial_step_rows;
  root["map_manager"] = map_policy_to_yaml(o.map);
  root["health"] = slam::health_to_yaml(o.health);
  root["simulation"]["preset"] = o.sim_preset;
  root["simulation"]["duration"] = o.sim_duration_s;
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
    ok = cv::imwrite(path, img);
  } catch (const cv::Exception& e) {
    throw IoError(fmt::format("{}: cannot write the overlay image ({})", path, e.what()));
  }
  if (!ok) throw IoError(fmt::format("{}: cannot write the overlay image", path));
}

}  // namespace

ImageSlamResult run_image_slam(io::Dataset& ds, const ImageSlamOptions& o,
                               const std::function<void(int, int)>& on_frame,
                               const std::function<void(const ImageSlamFrame&)>& observer,
                               const std::atomic<bool>* stop_requested) {
  if (!ds.source) throw ConfigError(fmt::format("dataset '{}' has no measurement source", ds.name));
  return run_image_slam(*ds.source, ds.rig, ds.name, o, on_frame, observer, stop_requested);
}

ImageSlamResult run_image_slam(io::Source& source, const io::Rig& rig, const std::string& name,
                               const ImageSlamOptions& o, const std::function<void(int, int)>& on_frame,
                               const std::function<void(const ImageSlamFrame&)>& observer,
                               const std::atomic<bool>* stop_requested) {
  o.validate();
  if (o.camera >= static_cast<int>(rig.cameras.size())) {
    throw ConfigError(fmt::format("slam/camera = {}: dataset '{}' has {} camera(s)", o.camera, name,
                                  rig.cameras.size()));
  }
  const io::CameraCalibration& cal = rig.cameras[static_cast<size_t>(o.camera)];
  const models::CameraIntrinsics intr = to_intrinsics(cal);
  const math::Pose T_RS = math::Pose::from_isometry(cal.T_RS);
  std::optional<KnownLandmarkSet> known;
  if (!o.known_landmarks.empty()) {
    known = load_known_landmarks(o.known_landmarks, o.known_landmarks_convention);
    if (o.known_landmarks_convention == "scenelib" &&
        (T_RS.p.norm() > 1e-9 || T_RS.q.angularDistance(Eigen::Quaterniond::Identity()) > 1e-9)) {
      throw ConfigError(fmt::format("slam/known_landmarks_convention = scenelib: the camera of '{}' must be the "
                                    "robot (T_RS = identity); use 'robot' when T_RS carries the frame change",
                                    name));
    }
  }

  const bool inertial = o.robot == "inertial";
  models::InertialParams imu_params;
  TimeNs t_d = 0;  // t_imu = t_cam + t_d
  double gyro_full_scale = 0.0, accel_full_scale = 0.0;  // 0: unknown
  if (inertial) {
    if (known) throw ConfigError("slam/known_landmarks is not supported with slam/robot = inertial yet");
    imu_params = inertial_params(rig.imu, o.imu, name);
    t_d = o.imu.time_offset_s ? from_seconds(*o.imu.time_offset_s) : rig.t_d;
    if (o.imu.gyro_saturation) gyro_full_scale = *o.imu.gyro_saturation;
    else if (rig.imu->gyro_saturation) gyro_full_scale = *rig.imu->gyro_saturation;
    if (o.imu.accel_saturation) accel_full_scale = *o.imu.accel_saturation;
    else if (rig.imu->accel_saturation) accel_full_scale = *rig.imu->accel_saturation;
  }

  slam::World world;
  filter::StateOptions so;
  so.tangent_capacity = o.state_capacity;
  if (o.consistency == "oc") so.nullspace_dim = slam::Robot::kNullspaceDim;
  slam::Map& map = world.add_map(so);
  auto map_manager = std::make_unique<strategies::PolicyMapManager>(o.map);
  const strategies::PolicyMapManager& mm = *map_manager;
  slam::System system(world, map, std::move(map_manager));
  std::unique_ptr<slam::Robot> robot_ptr;
  slam::InertialRobot* imu_robot = nullptr;
  if (inertial) {
    auto r = std::make_unique<slam::InertialRobot>(imu_params);
    imu_robot = r.get();
    robot_ptr = std::move(r);
  } else {
    robot_ptr = std::make_unique<slam::ConstantVelocityRobot>(o.motion);
  }
  slam::Sensor& sensor = robot_ptr->add_sensor(std::make_unique<slam::PinholeSensor>(cal.name, intr, T_RS));
  if (inertial && o.imu.estimate_extrinsics) {
    Eigen::Matrix<double, 6, 1> var;
    const double rot = o.imu.extrinsics_std_deg * M_PI / 180.0;
    var << Eigen::Vector3d::Constant(o.imu.extrinsics_std_m * o.imu.extrinsics_std_m), Eigen::Vector3d::Constant(rot * rot);
    sensor.estimate_extrinsics(var.asDiagonal());
  }
  slam::Robot* robot = nullptr;
  auto dm_ptr = std::make_unique<strategies::ActiveSearchDataManager>(o.search, mm, intr.width, intr.height,
                                                                      o.seed * 7919 + 1);
  strategies::ActiveSearchDataManager& dm = *dm_ptr;
  if (o.consistency == "fej") {
    dm_ptr->set_first_estimate_jacobians(true);
    robot_ptr->set_first_estimate_jacobians(true);
  }
  sensor.set_data_manager(std::move(dm_ptr));

  ImageSlamResult result;
  result.inertial = inertial;
  const auto total = source.image_count();
  const int n_total = total ? static_cast<int>(*total) : 0;
  // One entry per image: reserved when the count is known, so that the frame loop does not reallocate them.
  result.frames.reserve(static_cast<std::size_t>(n_total));
  result.estimate.poses.reserve(static_cast<std::size_t>(n_total));
  strategies::RawImage raw;
  int done = 0;       // images handed to the filter
  int consumed = 0;   // images taken from the stream (processed or not), for progress
  bool stop = false;
  // The last 2·init_window + 1 s of IMU samples: the start's window, and the health monitor's re-initializations.
  RingBuffer<ImuWindowSample> recent_imu(static_cast<std::size_t>(
      std::max(64.0, (2.0 * o.imu.init_window_s + o.imu.vi_init.max_window_s + 2.0) * (rig.imu ? std::max(rig.imu->rate_hz, 1.0) : 200.0) * 1.5)));
  const auto window_of = [&]() {
    std::vector<ImuWindowSample> w;
    w.reserve(recent_imu.size());
    for (std::size_t k = 0; k < recent_imu.size(); ++k) w.push_back(recent_imu[k]);
    return w;
  };
  slam::HealthMonitor monitor(o.health);
  Eigen::VectorXd last_good_x;  // the robot's state at the last healthy frame with enough corrections
  RingBuffer<io::ImageFrame> waiting(8);     // images not yet covered by the IMU
  std::optional<TimeNs> last_imu_t;

  // The health monitor's recovery drops every landmark; the robot then starts again through the same start
  // procedure (the inertial robot: its frames wait for a new visual-inertial or IMU-only start, `restarting`), in the
  // same world frame: at its last healthy position and heading, biases kept when plausible.
  bool restarting = false;
  // Places the robot at time t with the prior (x0, P0) of a start, expressed in its own start frame: the first start
  // attaches it to the map (that frame becomes the world frame), a restart re-initializes it in the current world.
  const auto begin_robot = [&](Eigen::VectorXd x0, const Eigen::MatrixXd& P0, TimeNs t) {
    if (robot == nullptr) {
      robot = &map.add_robot(std::move(robot_ptr), x0, P0, t);
      if (inertial) {
        for (std::size_t k = 0; k < recent_imu.size(); ++k) imu_robot->add_imu(recent_imu[k].t, recent_imu[k].m);
      }
      raw.sensor_id = sensor.id();
    } else {
      if (inertial) {
        using I = models::InertialIndex;
        // Heading: of the body axis most orthogonal to gravity, in both frames (see gravity_aligned_attitude).
        const Eigen::Quaterniond q_new = math::quat_from_wxyz(x0.segment<4>(I::kQ));
        const Eigen::Quaterniond q_old = math::quat_from_wxyz(last_good_x.segment<4>(I::kQ));
        const Eigen::Vector3d up_R = q_new.conjugate() * Eigen::Vector3d::UnitZ();
        int k = 0;
        up_R.cwiseAbs().minCoeff(&k);
        const Eigen::Vector3d h_new = q_new * Eigen::Vector3d::Unit(k), h_old = q_old * Eigen::Vector3d::Unit(k);
        const Eigen::Quaterniond Rz(Eigen::AngleAxisd(
            std::atan2(h_old.y(), h_old.x()) - std::atan2(h_new.y(), h_new.x()), Eigen::Vector3d::UnitZ()));
        x0.segment<3>(I::kP) = last_good_x.segment<3>(I::kP);
        x0.segment<4>(I::kQ) = math::quat_to_wxyz((Rz * q_new).normalized());
        x0.segment<3>(I::kV) = Rz * x0.segment<3>(I::kV);
        x0.segment<3>(I::kG) = Rz * x0.segment<3>(I::kG);
        if (last_good_x.segment<3>(I::kAb).norm() <= 0.5 * o.health.max_accel_bias &&
            last_good_x.segment<3>(I::kWb).norm() <= 0.5 * o.health.max_gyro_bias) {
          x0.segment<3>(I::kAb) = last_good_x.segment<3>(I::kAb);
          if (x0.segment<3>(I::kWb).isZero()) x0.segment<3>(I::kWb) = last_good_x.segment<3>(I::kWb);
        }
      } else {
        x0.head<7>() = last_good_x.head<7>();
      }
      robot->reset(x0, P0, t);
      restarting = false;
    }
    monitor.restart(t);
    last_good_x = map.state().mean(robot->block());
  };
  std::vector<ViInitFrame> init_frames;  // inertial robot: the visual-inertial start's window
  const auto vi_camera = std::make_unique<models::PinholeCamera>(intr);

  // Starts the filter at time t (the first image); false while the inertial window is incomplete.
  const auto start = [&](TimeNs t) -> bool {
    if (inertial) {
      if (recent_imu.empty() || recent_imu.front().t > t - from_seconds(o.imu.init_window_s)) return false;
      const InertialStart s0 = initialize_inertial(window_of(), t, o.imu);
      result.inertial_start = s0.describe();
      logger("slam")->info("inertial robot: {}", result.inertial_start);
      begin_robot(s0.x, s0.P, t);
      return true;
    } else {
      // The gauge: the first pose is the world frame (identity), with zero covariance.
      Eigen::VectorXd x0 = Eigen::VectorXd::Zero(13);
      x0.segment<4>(3) << 1.0, 0.0, 0.0, 0.0;
      Eigen::MatrixXd P0 = Eigen::MatrixXd::Zero(12, 12);
      P0.bottomRightCorner<6, 6>() =
          o.initial_velocity_std * o.initial_velocity_std * Eigen::MatrixXd::Identity(6, 6);
      if (known) {
        x0 = known->robot_mean;
        P0 = known->robot_cov;
      }
      const bool first = robot == nullptr;
      begin_robot(x0, P0, t);
      if (known && first) result.known_landmarks = add_known_landmarks(map, sensor, *known);
    }
    return true;
  };

  // The visual-inertial start (vi_init.hpp) over the buffered window: true once the robot is in the map at the
  // window's first image (the caller then processes the buffered images). While it fails the window slides; after
  // vi_init/max_wait of failures the IMU-only start takes over at the newest image.
  TimeNs first_image_t = -1;
  const auto try_vi_start = [&]() -> bool {
    if (first_image_t < 0) first_image_t = init_frames.front().t;
    if (init_frames.back().t - init_frames.front().t < from_seconds(o.imu.vi_init.window_s)) return false;
    const ViInitResult r = initialize_visual_inertial(init_frames, window_of(), *vi_camera, T_RS, o.imu.vi_init);
    if (r.kind != ViInitResult::Kind::Failed) {
      const InertialStart s0 = inertial_start_from_vi(r, o.imu);
      result.inertial_start = r.describe() + "; " + s0.describe();
      logger("slam")->info("inertial robot: {}", result.inertial_start);
      begin_robot(s0.x, s0.P, init_frames.front().t);
      if (r.kind == ViInitResult::Kind::Dynamic) dm.set_depth_hint(r.median_depth_m);
      return true;
    }
    logger("slam")->debug("visual-inertial start at t = {:.3f} s: {}", to_seconds(init_frames.front().t), r.reason);
    if (init_frames.back().t - first_image_t > from_seconds(o.imu.vi_init.max_window_s + o.imu.vi_init.max_wait_s) &&
        start(init_frames.back().t)) {
      logger("slam")->info("visual-inertial start failed for {:.1f} s ({}): IMU-only start", o.imu.vi_init.max_wait_s,
                           r.reason);
      result.images_before_start += static_cast<int>(init_frames.size()) - 1;
      init_frames.erase(init_frames.begin(), init_frames.end() - 1);
      return true;
    }
    // Not enough parallax or excitation yet: the window grows (up to max_window); else it slides.
    if (r.needs_longer_window &&
        init_frames.back().t - init_frames.front().t < from_seconds(o.imu.vi_init.max_window_s)) {
      return false;
    }
    init_frames.erase(init_frames.begin());
    ++result.images_before_start;
    return false;
  };

  // One image through the filter (the robot is in the map).
  const auto filter_image = [&](const cv::Mat& image, TimeNs t) {
    if (stop) return;
    raw.t = t;
    raw.image = vision::ImageView{image.data, image.cols, image.rows, static_cast<int>(image.step[0])};
    slam::FrameStats& fs = result.frames.emplace_back(system.process(raw));
    StampedPose est;
    est.t = t;
    const math::Pose T_WR = robot->pose();
    est.p_WR = T_WR.p;
    est.q_WR = T_WR.q;
    const auto x = map.state().mean(robot->block());
    est.v_WR = x.segment<3>(7);
    if (inertial) {
      est.accel_bias = x.segment<3>(models::InertialIndex::kAb);
      est.gyro_bias = x.segment<3>(models::InertialIndex::kWb);
    }
    est.cov = map.state().cov(robot->block()).topLeftCorner<6, 6>();
    result.estimate.poses.push_back(est);
    const slam::HealthMonitor::Verdict verdict = monitor.check(map, *robot, fs);
    fs.health = static_cast<int>(verdict.health);
    if (!verdict.note.empty()) logger("slam")->warn("t = {:.3f} s: {}", to_seconds(t), verdict.note);
    result.final_health = verdict.health;
    if (verdict.health == slam::Health::Ok) {
      if (fs.updated >= o.health.min_updated) last_good_x = x;
    } else {
      ++(verdict.health == slam::Health::Lost ? result.frames_lost : result.frames_diverged);
      logger("slam")->warn("t = {:.3f} s: tracking {}: {}{}", to_seconds(t), slam::to_string(verdict.health),
                           verdict.reason, o.health.reset ? "; re-initializing" : "");
      if (o.health.reset) {
        while (!map.landmarks().empty()) map.remove_landmark(*map.landmarks().back());
        fs.reset = true;
        ++result.resets;
        if (inertial) {
          restarting = true;  // the next images go to the start procedure
          first_image_t = -1;
        } else {
          start(t);  // the constant-velocity robot starts again at once, at rest
        }
      }
    }
    if (observer || done == o.overlay_frame) {
      const ImageSlamFrame f{done, t, &map, &dm.last_frame(), &image, &fs, &dm.grid(), &result.estimate.poses.back()};
      if (done == o.overlay_frame) write_overlay(o.overlay_path, f, o.search.n_sigma);
      if (observer) observer(f);
    }
    ++done;
    if (o.max_frames > 0 && done >= o.max_frames) stop = true;
  };


  const auto process_image = [&](const io::ImageFrame& frame) {
    ++consumed;
    const TimeNs t = frame.t + t_d;
    if ((robot == nullptr || restarting) && inertial && o.imu.vi_init.enabled) {
      init_frames.push_back(ViInitFrame{t, frame.image});
      if (try_vi_start()) {
        for (const ViInitFrame& f : init_frames) filter_image(f.image, f.t);
        init_frames.clear();
        init_frames.shrink_to_fit();
      }
      if (on_frame) on_frame(consumed, n_total);
      return;
    }
    if ((robot == nullptr || restarting) && !start(t)) {
      ++result.images_before_start;
      if (result.images_before_start == 1) {
        logger("slam")->info("waiting for {:.2f} s of IMU data before the first image to start the inertial robot",
                             o.imu.init_window_s);
      }
      if (on_frame) on_frame(consumed, n_total);
      return;
    }
    filter_image(frame.image, t);
    if (on_frame) on_frame(consumed, n_total);
  };
  while (!stop) {
    if (stop_requested != nullptr && stop_requested->load()) {
      stop = true;
      break;
    }
    auto m = source.next();
    if (!m) break;
    if (const auto* imu = std::get_if<io::ImuSample>(&*m)) {
      if (!inertial) continue;
      ++result.imu_samples;
      last_imu_t = imu->t;
      if (gyro_full_scale > 0.0 && imu->gyro.cwiseAbs().maxCoeff() >= gyro_full_scale) ++result.imu_gyro_saturated;
      if (accel_full_scale > 0.0 && imu->accel.cwiseAbs().maxCoeff() >= accel_full_scale) ++result.imu_accel_saturated;
      const models::ImuMeasurement mm_imu{imu->accel, imu->gyro};
      if (!recent_imu.empty() && imu->t <= recent_imu.back().t) {
        throw DataError(fmt::format("IMU sample at t = {} ns is not after the previous one", imu->t));
      }
      if (recent_imu.size() + 1 >= recent_imu.capacity()) recent_imu.pop_front();
      recent_imu.push_back({imu->t, mm_imu});
      if (robot != nullptr) imu_robot->add_imu(imu->t, mm_imu);
      while (!stop && !waiting.empty() && waiting.front().t + t_d <= imu->t) {
        process_image(waiting.front());
        waiting.pop_front();
      }
      continue;
    }
    auto* frame = std::get_if<io::ImageFrame>(&*m);
    if (frame == nullptr || frame->camera != o.camera) continue;
    if (frame->image.type() != CV_8UC1) throw DataError(fmt::format("{}: image is not 8-bit grey", frame->path));
    if (!inertial) {
      process_image(*frame);
      continue;
    }
    waiting.push_back(std::move(*frame));
    // At equal timestamps the IMU sample comes first: an image may be covered on arrival.
    while (!stop && !waiting.empty() && last_imu_t && waiting.front().t + t_d <= *last_imu_t) {
      process_image(waiting.front());
      waiting.pop_front();
    }
    if (waiting.size() > 200) {
      throw DataError(fmt::format("{}: 200 images wait for IMU data (the IMU stream stops or lags behind the camera)",
                                  waiting.back().path));
    }
  }
  result.images_not_covered = static_cast<int>(stop ? 0 : waiting.size());
  if (result.images_not_covered > 0) {
    logger("slam")->warn("{} image(s) after the last IMU sample were not processed", result.images_not_covered);
  }
  if (imu_robot != nullptr && robot != nullptr) {
    result.imu_samples_integrated = imu_robot->samples_integrated();
    const auto x = map.state().mean(robot->block());
    result.gravity_W = x.segment<3>(models::InertialIndex::kG);
    result.accel_bias = x.segment<3>(models::InertialIndex::kAb);
    result.gyro_bias = x.segment<3>(models::InertialIndex::kWb);
  }
  result.T_RS_calibration = T_RS;
  result.T_RS_estimate = T_RS;
  if (sensor.block() != filter::kNoBlock && robot != nullptr) {
    result.extrinsics_estimated = true;
    result.T_RS_estimate = sensor.T_RS(map.state().mean_vector());
    result.T_RS_std = map.state().cov(sensor.block()).diagonal().cwiseSqrt();
  }
  if (robot == nullptr) throw DataError(fmt::format("dataset '{}' has no image of camera {}", name, o.camera));
  result.frame_gaps = monitor.frame_gaps();
  const Eigen::VectorXd& mean = map.state().mean_vector();
  const Eigen::Vector3d p_WS = sensor.pose_in_world(mean).p;
  for (const auto& l : map.landmarks()) {
    result.landmarks_created = std::max(result.landmarks_created, l->id() + 1);
    if (l->type() == slam::LandmarkType::EuclideanPoint) ++result.euclidean_final;
    const Eigen::Vector3d p = l->position(mean);
    Eigen::Matrix3d cov;
    const auto P = map.state().cov(l->block());
    if (l->type() == slam::LandmarkType::EuclideanPoint) {
      cov = P;
    } else {
      const auto L = map.state().mean(l->block());
      const double rho = L[6];
      Eigen::Matrix<double, 3, 7> J;
      J << Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity() / rho, -L.segment<3>(3) / (rho * rho);
      cov = J * P * J.transpose();
    }
    result.landmark_ids.push_back(l->id());
    result.landmark_positions.push_back(p);
    result.landmark_covariances.push_back(cov);
    result.landmark_depths.push_back((p - p_WS).norm());
  }
  result.landmarks_final = static_cast<int>(map.landmarks().size());
  result.estimate.source = fmt::format("rtslam image SLAM on {}", name);
  return result;
}

}  // namespace rtslam::pipeline
