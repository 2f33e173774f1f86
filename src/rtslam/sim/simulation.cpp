#include "rtslam/sim/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numbers>
#include <utility>
#include <variant>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/trajectory_io.hpp"
#include "rtslam/io/writers.hpp"

namespace rtslam::sim {

namespace fs = std::filesystem;
using Eigen::Vector3d;

std::uint64_t mix_seed(std::uint64_t seed, std::uint64_t stream, std::uint64_t index) {
  auto splitmix = [](std::uint64_t x) {
    x += 0x9E3779B97F4A7C15ULL;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
    return x ^ (x >> 31);
  };
  return splitmix(splitmix(splitmix(seed) ^ stream) ^ index);
}

io::CameraCalibration SimConfig::euroc_cam0() {
  io::CameraCalibration c;
  c.name = "cam0";
  c.width = 752;
  c.height = 480;
  c.rate_hz = 20.0;
  c.fx = 458.654;
  c.fy = 457.296;
  c.cx = 367.215;
  c.cy = 248.375;
  c.distortion = io::DistortionModel::RadTan;
  c.distortion_coeffs = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  Eigen::Matrix4d T;
  T << 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975,  //
      0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768,       //
      -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949,   //
      0.0, 0.0, 0.0, 1.0;
  // The file's rotation is orthonormal to ~1e-9 only: re-orthonormalize so that T_RS is an exact rigid transform.
  Eigen::Matrix3d R = Eigen::Quaterniond(T.topLeftCorner<3, 3>()).normalized().toRotationMatrix();
  c.T_RS.linear() = R;
  c.T_RS.translation() = T.topRightCorner<3, 1>();
  return c;
}

io::CameraCalibration SimConfig::euroc_cam1() {
  io::CameraCalibration c;
  c.name = "cam1";
  c.width = 752;
  c.height = 480;
  c.rate_hz = 20.0;
  c.fx = 457.587;
  c.fy = 456.134;
  c.cx = 379.999;
  c.cy = 255.238;
  c.distortion = io::DistortionModel::RadTan;
  c.distortion_coeffs = {-0.28368365, 0.07451284, -0.00010473, -3.55590700e-05};
  Eigen::Matrix4d T;
  T << 0.0125552670891, -0.999755099723, 0.0182237714554, -0.0198435579556,  //
      0.999598781151, 0.0130119051815, 0.0251588363115, 0.0453689425024,     //
      -0.0253898008918, 0.0179005838253, 0.999517347078, 0.00786212447038,   //
      0.0, 0.0, 0.0, 1.0;
  c.T_RS.linear() = Eigen::Quaterniond(T.topLeftCorner<3, 3>()).normalized().toRotationMatrix();
  c.T_RS.translation() = T.topRightCorner<3, 1>();
  return c;
}

std::vector<std::string> SimConfig::preset_names() { return {"handheld", "high-dynamic", "hall", "ground"}; }

SimConfig SimConfig::preset(const std::string& name) {
  SimConfig c;
  c.name = name;
  if (name == "handheld") {
    // defaults
  } else if (name == "high-dynamic") {
    c.trajectory = "high-dynamic";
    c.duration_s = 45.0;
    c.camera.rate_hz = 50.0;  // as in the paper
    c.render.exposure_s = 0.003;
  } else if (name == "hall") {
    c.world = WorldConfig::preset("hall");
  } else if (name == "ground") {
    c.world = WorldConfig::preset("hall");
    c.trajectory = "ground";
    c.odometry.enabled = true;  // a wheeled robot: its wheel odometry, with the default noise
  } else {
    throw ConfigError(
        fmt::format("simulation preset '{}' is unknown (known: handheld, high-dynamic, hall, ground)", name));
  }
  return c;
}

models::CameraIntrinsics to_intrinsics(const io::CameraCalibration& cam) {
  models::CameraIntrinsics in;
  in.width = cam.width;
  in.height = cam.height;
  in.fx = cam.fx;
  in.fy = cam.fy;
  in.cx = cam.cx;
  in.cy = cam.cy;
  in.coeffs = cam.distortion_coeffs;
  switch (cam.distortion) {
    case io::DistortionModel::None: in.model = models::DistortionModel::None; break;
    case io::DistortionModel::RadTan: in.model = models::DistortionModel::RadTan; break;
    case io::DistortionModel::Equidistant: in.model = models::DistortionModel::Equidistant; break;
    case io::DistortionModel::MonoSlamOneParam: in.model = models::DistortionModel::MonoSlam; break;
  }
  return in;
}

namespace {

std::string resolve(const std::string& path, const std::string& dir) {
  if (path.empty() || dir.empty() || fs::path(path).is_absolute()) return path;
  const fs::path p = fs::path(dir) / path;
  return fs::exists(p) ? p.string() : path;
}

}  // namespace

SimConfig SimConfig::from_yaml(YamlMap& m, SimConfig c, const std::string& dir) {
  m.get("name", c.name);
  m.get("seed", c.seed);
  if (m.has("trajectory_seed")) c.trajectory_seed = m.require<std::uint64_t>("trajectory_seed");
  m.get("duration", c.duration_s);
  m.get("start_time", c.start_time_s);
  m.get("trajectory", c.trajectory);
  if (c.trajectory.rfind("follow:", 0) == 0) c.trajectory = "follow:" + resolve(c.trajectory.substr(7), dir);
  if (c.recorded()) c.trajectory = "recorded:" + resolve(c.trajectory.substr(9), dir);
  m.get("follow_knot_spacing", c.follow_knot_spacing_s);
  m.get("ground_speed", c.ground_speed_mps);
  m.get("start_offset", c.start_offset_s);
  m.get("stereo", c.stereo);
  if (m.has("world")) {
    const YAML::Node w = m.node()["world"];
    if (w.IsScalar()) {
      const std::string s = m.require<std::string>("world");
      const auto names = WorldConfig::preset_names();
      c.world = std::find(names.begin(), names.end(), s) != names.end() ? WorldConfig::preset(s)
                                                                         : WorldConfig::from_file(resolve(s, dir));
    } else {
      YamlMap wm = m.child("world");
      c.world = WorldConfig::from_yaml(wm);
    }
  }
  if (m.has("camera")) {
    YamlMap cm = m.child("camera");
    if (cm.has("calibration")) {
      const std::string cal = cm.require<std::string>("calibration");
      if (cal != "euroc-cam0") {
        const io::Rig rig = io::load_calibration(resolve(cal, dir));
        if (rig.cameras.empty()) throw ConfigError(fmt::format("{}: calibration '{}' has no camera", cm.where(), cal));
        c.camera = rig.cameras.front();
        if (c.camera.rate_hz <= 0.0) c.camera.rate_hz = 20.0;
      }
    }
    cm.get("rate_hz", c.camera.rate_hz);
    cm.get("supersampling", c.render.supersampling);
    cm.get("noise_std", c.render.noise_std);
    cm.get("motion_blur", c.render.motion_blur);
    cm.get("exposure", c.render.exposure_s);
    if (cm.has("time_offset_ms")) c.camera_time_offset_s = 1e-3 * cm.require<double>("time_offset_ms");
    cm.finish();
  }
  if (m.has("imu")) {
    YamlMap im = m.child("imu");
    im.get("enabled", c.imu_enabled);
    c.imu.read(im);
    im.finish();
  }
  if (m.has("odometry")) {
    YamlMap om = m.child("odometry");
    c.odometry.read(om);
    om.finish();
  }
  m.get("threads", c.render.threads);
  for (const auto& [key, pose] : {std::pair<const char*, bool>{"gps", false}, {"mocap", true}}) {
    if (!m.has(key)) continue;
    YamlMap am = m.child(key);
    (pose ? c.mocap : c.gps).read(am, pose);
    am.finish();
  }
  m.finish();
  c.validate();
  return c;
}

SimConfig SimConfig::load(const std::string& name_or_file) {
  const auto names = preset_names();
  if (std::find(names.begin(), names.end(), name_or_file) != names.end()) return preset(name_or_file);
  if (!fs::exists(name_or_file))
    throw ConfigError(fmt::format("simulation preset '{}' is neither a built-in preset (handheld, high-dynamic, "
                                  "hall) nor a file",
                                  name_or_file));
  YamlMap m(load_yaml_file(name_or_file), name_or_file);
  // A file may start from a built-in preset (`base: high-dynamic`) and override parts.
  SimConfig base;
  if (m.has("base")) base = preset(m.require<std::string>("base"));
  return from_yaml(m, base, fs::path(name_or_file).parent_path().string());
}

void SimConfig::validate() const {
  const std::string where = "simulation '" + name + "'";
  require_bound(duration_s > 0.0 && duration_s <= 3600.0, where, "duration", duration_s, "in (0, 3600] s");
  require_bound(start_time_s >= 0.0 && start_time_s < 1e9, where, "start_time", start_time_s, "in [0, 1e9) s");
  require_bound(follow_knot_spacing_s >= 0.005 && follow_knot_spacing_s <= 1.0, where, "follow_knot_spacing",
                follow_knot_spacing_s, "in [0.005, 1] s");
  require_bound(camera.rate_hz > 0.0 && camera.rate_hz <= 1000.0, where, "camera.rate_hz", camera.rate_hz,
                "in (0, 1000] Hz");
  if (trajectory != "handheld" && trajectory != "high-dynamic" && trajectory != "ground" &&
      trajectory.rfind("follow:", 0) != 0 && !recorded())
    throw ConfigError(fmt::format(
        "{}: trajectory = '{}' must be handheld, high-dynamic, ground, follow:FILE or recorded:DIR", where, trajectory));
  require_bound(ground_speed_mps > 0.0 && ground_speed_mps <= 10.0, where, "ground_speed", ground_speed_mps,
                "in (0, 10] m/s");
  if (trajectory == "follow:") throw ConfigError(fmt::format("{}: trajectory 'follow:' needs a file", where));
  if (trajectory == "recorded:") throw ConfigError(fmt::format("{}: trajectory 'recorded:' needs a folder", where));
  require_bound(start_offset_s >= 0.0 && start_offset_s < 1e6, where, "start_offset", start_offset_s, "in [0, 1e6) s");
  if (start_offset_s > 0.0 && (trajectory == "handheld" || trajectory == "high-dynamic" || trajectory == "ground"))
    throw ConfigError(fmt::format("{}: start_offset applies to follow:FILE and recorded:DIR trajectories only", where));
  if (recorded() && !imu_enabled)
    throw ConfigError(fmt::format("{}: a recorded:DIR trajectory replays the recorded IMU: imu.enabled must be true", where));
  world.validate(where + " world");
  imu.validate(where + " imu");
  odometry.validate(where + " odometry");
  if (recorded() && odometry.enabled)
    throw ConfigError(fmt::format("{}: odometry is synthesized for synthetic and follow:FILE trajectories only", where));
  require_bound(render.supersampling >= 1 && render.supersampling <= 8, where, "camera.supersampling",
                render.supersampling, "in [1, 8]");
  require_bound(render.noise_std >= 0.0, where, "camera.noise_std", render.noise_std, ">= 0");
  require_bound(render.exposure_s >= 0.0 && render.exposure_s < 1.0 / camera.rate_hz, where, "camera.exposure",
                render.exposure_s, "in [0, 1/rate)");
  require_bound(std::abs(camera_time_offset_s) <= 0.5, where, "camera.time_offset_ms", 1e3 * camera_time_offset_s,
                "within ±500 ms");
  require_bound(render.threads >= 1 && render.threads <= 64, where, "threads", render.threads, "in [1, 64]");
  gps.validate(where + " gps");
  mocap.validate(where + " mocap");
}

std::shared_ptr<const Simulation> Simulation::create(const SimConfig& config) {
  return std::shared_ptr<const Simulation>(new Simulation(config));
}

Simulation::Simulation(const SimConfig& config) : config_(config) {
  config_.validate();
  time_offset_ = from_seconds(config_.camera_time_offset_s);
  auto log = logger("sim");
  const std::uint64_t traj_seed = config_.trajectory_seed.value_or(config_.seed);
  const TimeNs t_start = from_seconds(config_.start_time_s);
  const bool follow = config_.trajectory.rfind("follow:", 0) == 0;
  const bool recorded = config_.recorded();
  std::optional<Trajectory> recorded_states;
  std::vector<io::ImuSample> recorded_imu;
  if (recorded) {
    // The folder's calibrations (cameras relative to the IMU) and recorded streams; images of the folder are not
    // read (the renderer makes them).
    const std::string dir = config_.trajectory.substr(9);
    const fs::path root = fs::is_directory(fs::path(dir) / "mav0") ? fs::path(dir) / "mav0" : fs::path(dir);
    const fs::path states = root / "state_groundtruth_estimate0" / "data.csv";
    if (!fs::is_regular_file(states))
      throw ConfigError(fmt::format("simulation '{}': recorded:{} has no {} to follow", config_.name, dir,
                                    states.string()));
    if (!fs::is_regular_file(root / "imu0" / "sensor.yaml"))
      throw ConfigError(fmt::format("simulation '{}': recorded:{} has no imu0/sensor.yaml", config_.name, dir));
    // Cameras relative to the IMU (our robot frame R): T_RS = T_BI⁻¹ T_BS with EuRoC's body frame B.
    const io::ImuCalibration imu_cal = io::load_euroc_imu((root / "imu0" / "sensor.yaml").string());
    const auto camera_of = [&](int c) {
      io::CameraCalibration cam = io::load_euroc_camera((root / fmt::format("cam{}", c) / "sensor.yaml").string());
      cam.T_RS = imu_cal.T_RS.inverse() * cam.T_RS;
      return cam;
    };
    const RenderOptions keep_render = config_.render;
    config_.camera = camera_of(0);
    if (config_.stereo) config_.camera1 = camera_of(1);
    config_.render = keep_render;
    config_.imu.rate_hz = imu_cal.rate_hz;
    config_.imu.noise.gyro_noise_density = imu_cal.gyro_noise_density;
    config_.imu.noise.gyro_random_walk = imu_cal.gyro_random_walk;
    config_.imu.noise.accel_noise_density = imu_cal.accel_noise_density;
    config_.imu.noise.accel_random_walk = imu_cal.accel_random_walk;
    recorded_states = io::read_trajectory(states.string(), io::TrajectoryFormat::EurocCsv);
    if (recorded_states->poses.size() < 2)
      throw DataError(fmt::format("{}: fewer than 2 states to follow", states.string()));
    io::DatasetOptions imu_only;
    imu_only.cameras = {};
    io::Dataset stream = io::open_dataset("euroc:" + dir, imu_only);
    while (auto m = stream.source->next())
      if (const auto* s = std::get_if<io::ImuSample>(&*m)) recorded_imu.push_back(*s);
    if (recorded_imu.empty()) throw DataError(fmt::format("{}/imu0/data.csv: no IMU sample", dir));
    trajectory_ = std::make_unique<RecordedTrajectory>(*recorded_states);
  } else if (follow) {
    trajectory_ = make_follow(config_.trajectory.substr(7), config_.follow_knot_spacing_s);
  } else if (config_.trajectory == "ground") {
    const WorldConfig& w = config_.world;
    const Vector3d center(w.room_center.x(), w.room_center.y(), w.floor_z + std::min(0.5, 0.5 * w.room_size.z()));
    trajectory_ = make_ground(traj_seed, center, w.room_size.head<2>(), config_.ground_speed_mps,
                              config_.duration_s + 1.0, t_start);
  } else {
    const WorldConfig& w = config_.world;
    const Vector3d center(w.room_center.x(), w.room_center.y(), w.floor_z + std::min(1.5, 0.5 * w.room_size.z()));
    // Long enough for the requested duration (the end is clamped anyway).
    trajectory_ = config_.trajectory == "handheld"
                      ? make_handheld(traj_seed, center, config_.duration_s + 1.0, t_start)
                      : make_high_dynamic(traj_seed, center, config_.duration_s + 1.0, t_start);
  }
  const TimeNs t0 = trajectory_->t_begin() + from_seconds(config_.start_offset_s);
  if (t0 >= trajectory_->t_end())
    throw ConfigError(fmt::format("simulation '{}': start_offset = {} s is past the end of {} ({:.1f} s long)",
                                  config_.name, config_.start_offset_s, trajectory_->describe(),
                                  to_seconds(trajectory_->t_end() - trajectory_->t_begin())));
  const TimeNs t1 = std::min(trajectory_->t_end(), t0 + from_seconds(config_.duration_s));

  // The world must contain the path with some room around it.
  std::vector<Vector3d> path;
  for (TimeNs t = t0; t <= t1; t += 50'000'000) path.push_back(trajectory_->at(t).p_WR);
  if (follow || recorded || config_.trajectory == "ground") {  // a ground robot's laps clear their own way
    const int removed = config_.world.fit_to_points(path, 1.0, 0.3);
    log->info("world fitted around {}: room {:.1f} x {:.1f} x {:.1f} m, {} obstacle(s) removed from the path",
              trajectory_->describe(), config_.world.room_size.x(), config_.world.room_size.y(),
              config_.world.room_size.z(), removed);
  }
  world_ = std::make_unique<World>(config_.world);
  for (std::size_t i = 0; i < path.size(); ++i)
    if (!world_->is_free(path[i], 0.2))
      throw ConfigError(fmt::format("simulation '{}': the {} trajectory passes within 0.2 m of a wall or obstacle at "
                                    "t = {:.2f} s (p = [{:.2f}, {:.2f}, {:.2f}]); choose another world or seed",
                                    config_.name, trajectory_->describe(), 0.05 * static_cast<double>(i), path[i].x(),
                                    path[i].y(), path[i].z()));

  // Cameras and the rig.
  rig_.cameras = {config_.camera};
  if (config_.stereo) rig_.cameras.push_back(config_.camera1);
  for (const io::CameraCalibration& cal : rig_.cameras) {
    cameras_.push_back(std::make_unique<models::PinholeCamera>(to_intrinsics(cal)));
    renderers_.push_back(std::make_unique<Renderer>(*world_, *cameras_.back(), config_.render));
    T_RS_.push_back(math::Pose{Eigen::Quaterniond(cal.T_RS.rotation()).normalized(), cal.T_RS.translation()});
  }
  if (config_.imu_enabled) {
    io::ImuCalibration imu;
    imu.rate_hz = config_.imu.rate_hz;
    imu.gyro_noise_density = config_.imu.noise.gyro_noise_density;
    imu.gyro_random_walk = config_.imu.noise.gyro_random_walk;
    imu.accel_noise_density = config_.imu.noise.accel_noise_density;
    imu.accel_random_walk = config_.imu.noise.accel_random_walk;
    if (config_.imu.gyro_saturation_deg_s > 0.0) imu.gyro_saturation = config_.imu.gyro_saturation_deg_s * std::numbers::pi / 180.0;
    if (config_.imu.accel_saturation > 0.0) imu.accel_saturation = config_.imu.accel_saturation;
    rig_.imu = imu;
  }

  // Absolute fixes from the ground truth, each from its own seeded stream.
  if (config_.gps.enabled) gps_ = make_position_fixes(*trajectory_, t0, t1, config_.gps, mix_seed(config_.seed, 5));
  if (config_.mocap.enabled) mocap_ = make_pose_fixes(*trajectory_, t0, t1, config_.mocap, mix_seed(config_.seed, 6));

  ground_truth_.source = "simulation:" + config_.name;
  if (recorded) {
    // Images at the recorded states' timestamps (EuRoC's camera timestamps), the recorded IMU over the same window,
    // the recorded states as the ground truth.
    for (const StampedPose& p : recorded_states->poses) {
      if (p.t < t0 || p.t > t1) continue;
      image_times_.push_back(p.t);
      ground_truth_.poses.push_back(p);
    }
    for (const io::ImuSample& m : recorded_imu) {
      if (m.t < t0 || m.t > t1) continue;
      SynthImuSample s;
      s.t = m.t;
      s.gyro = m.gyro;
      s.accel = m.accel;
      imu_.push_back(s);
    }
    if (image_times_.empty() || imu_.empty())
      throw DataError(fmt::format("simulation '{}': the window [{:.3f}, {:.3f}] s of {} holds {} states and {} IMU "
                                  "samples", config_.name, to_seconds(t0), to_seconds(t1), trajectory_->describe(),
                                  image_times_.size(), imu_.size()));
    log->info("simulation '{}': {}, {:.1f} s, {} images x {} camera(s) at the recorded timestamps, {} recorded IMU "
              "samples, seed {}", config_.name, trajectory_->describe(), to_seconds(t1 - t0), image_times_.size(),
              cameras_.size(), imu_.size(), config_.seed);
    return;
  }

  // Image times: t0 + k / rate (exact ns from the rate's period; the exposure centre is the timestamp).
  const double period_ns = 1e9 / config_.camera.rate_hz;
  for (std::size_t k = 0;; ++k) {
    const TimeNs t = t0 + static_cast<TimeNs>(std::llround(static_cast<double>(k) * period_ns));
    if (t > t1) break;
    image_times_.push_back(t);
  }

  // IMU samples (all at once: cheap, and the ground truth needs the biases).
  if (config_.imu_enabled) {
    ImuSynthesizer synth(*trajectory_, config_.imu, Rng(mix_seed(config_.seed, 1)));
    const double imu_period_ns = 1e9 / config_.imu.rate_hz;
    for (std::size_t k = 0;; ++k) {
      const TimeNs t = t0 + static_cast<TimeNs>(std::llround(static_cast<double>(k) * imu_period_ns));
      if (t > t1) break;
      imu_.push_back(synth.sample(t));
    }
  }
  if (config_.odometry.enabled) {
    // Stream 7: 5 and 6 are the GPS and mocap fixes'.
    odometry_ = synthesize_odometry(*trajectory_, t0, t1, config_.odometry, Rng(mix_seed(config_.seed, 7)));
  }
  auto gt_pose = [this](TimeNs t) {
    const KinematicState s = trajectory_->at(t);
    StampedPose p;
    p.t = t;
    p.p_WR = s.p_WR;
    p.q_WR = s.q_WR;
    p.v_WR = s.v_WR;
    return p;
  };
  if (!imu_.empty()) {
    for (const SynthImuSample& s : imu_) {
      StampedPose p = gt_pose(s.t);
      p.gyro_bias = s.gyro_bias;
      p.accel_bias = s.accel_bias;
      ground_truth_.poses.push_back(p);
    }
  } else {
    for (TimeNs t : image_times_) ground_truth_.poses.push_back(gt_pose(t));
  }
  log->info("simulation '{}': {}, {:.1f} s, {} images x {} camera(s) at {} Hz, {} IMU samples, seed {}", config_.name,
            trajectory_->describe(), to_seconds(t1 - t0), image_times_.size(), cameras_.size(), config_.camera.rate_hz,
            imu_.size(), config_.seed);
}

math::Pose Simulation::camera_pose(TimeNs t, int c) const {
  const KinematicState s = trajectory_->at(t);
  math::Pose T_WR;
  T_WR.q = s.q_WR;
  T_WR.p = s.p_WR;
  return T_WR * T_RS_.at(static_cast<std::size_t>(c));
}

cv::Mat Simulation::render_image(std::size_t k, int c) const {
  const TimeNs t = image_times_.at(k);
  const Renderer& renderer = *renderers_.at(static_cast<std::size_t>(c));
  std::vector<math::Pose> poses;
  for (double dt : renderer.pose_time_offsets()) poses.push_back(camera_pose(t + from_seconds(dt), c));
  // Camera 0 keeps the noise stream it always had (same images as before stereo existed).
  const std::uint64_t stream = c == 0 ? 2 : 2 + 16 * static_cast<std::uint64_t>(c);
  return renderer.render(poses, mix_seed(config_.seed, stream, k));
}

namespace {

class SimSource final : public io::Source {
 public:
  explicit SimSource(std::shared_ptr<const Simulation> sim) : sim_(std::move(sim)) {}

  std::optional<io::Measurement> next() override {
    const auto& imu = sim_->imu_samples();
    const auto& img = sim_->image_times();
    const auto& odo = sim_->odometry();
    const bool has_imu = imu_pos_ < imu.size(), has_img = img_pos_ < img.size(), has_odo = odo_pos_ < odo.size();
    // Absolute fixes come after the IMU samples, odometry readings and images of their time (none while a stereo pair
    // is half out).
    const auto& gps = sim_->gps_fixes();
    const auto& mocap = sim_->mocap_fixes();
    if (cam_ == 0) {
      const TimeNs t_other = std::min({has_imu ? imu[imu_pos_].t : kNoTime, has_odo ? odo[odo_pos_].t : kNoTime,
                                       has_img ? sim_->image_stamp(img_pos_) : kNoTime});
      if (gps_pos_ < gps.size() && gps[gps_pos_].t < t_other &&
          (mocap_pos_ >= mocap.size() || gps[gps_pos_].t <= mocap[mocap_pos_].t)) {
        return gps[gps_pos_++];
      }
      if (mocap_pos_ < mocap.size() && mocap[mocap_pos_].t < t_other) return mocap[mocap_pos_++];
    }
    if (!has_imu && !has_img && !has_odo) return std::nullopt;
    const bool odo_before_img = has_odo && (!has_img || odo[odo_pos_].t <= sim_->image_stamp(img_pos_));
    if (has_imu && (!has_img || imu[imu_pos_].t <= sim_->image_stamp(img_pos_)) &&
        (!has_odo || imu[imu_pos_].t <= odo[odo_pos_].t)) {
      const SynthImuSample& s = imu[imu_pos_++];
      ++stats_.imu_samples;
      return io::ImuSample{s.t, s.gyro, s.accel};
    }
    if (odo_before_img) {
      const SynthOdometry& o = odo[odo_pos_++];
      return io::OdometrySample{o.t, o.t_from, o.dp, o.dtheta};
    }
    io::ImageFrame f;
    f.t = sim_->image_stamp(img_pos_);
    f.camera = cam_;
    f.image = sim_->render_image(img_pos_, cam_);
    f.path = cam_ == 0 ? fmt::format("sim:{}#{}", sim_->config().name, img_pos_)
                       : fmt::format("sim:{}#{}/cam{}", sim_->config().name, img_pos_, cam_);
    if (++cam_ == sim_->camera_count()) {
      cam_ = 0;
      ++img_pos_;
    }
    ++stats_.images;
    return f;
  }
  const io::SourceStats& stats() const override { return stats_; }
  std::optional<std::size_t> image_count() const override {
    return sim_->image_times().size() * static_cast<std::size_t>(sim_->camera_count());
  }
  // Skips without rendering.
  bool seek(TimeNs t) override {
    const auto& imu = sim_->imu_samples();
    const auto& img = sim_->image_times();
    while (imu_pos_ < imu.size() && imu[imu_pos_].t < t) ++imu_pos_;
    while (img_pos_ < img.size() && sim_->image_stamp(img_pos_) < t) ++img_pos_;
    while (odo_pos_ < sim_->odometry().size() && sim_->odometry()[odo_pos_].t < t) ++odo_pos_;
    while (gps_pos_ < sim_->gps_fixes().size() && sim_->gps_fixes()[gps_pos_].t < t) ++gps_pos_;
    while (mocap_pos_ < sim_->mocap_fixes().size() && sim_->mocap_fixes()[mocap_pos_].t < t) ++mocap_pos_;
    cam_ = 0;
    return true;
  }

 private:
  std::shared_ptr<const Simulation> sim_;
  static constexpr TimeNs kNoTime = std::numeric_limits<TimeNs>::max();
  std::size_t imu_pos_ = 0, img_pos_ = 0, odo_pos_ = 0, gps_pos_ = 0, mocap_pos_ = 0;
  int cam_ = 0;
  io::SourceStats stats_;
};

}  // namespace

std::unique_ptr<io::Source> Simulation::make_source() const {
  return std::make_unique<SimSource>(shared_from_this());
}

io::Dataset Simulation::make_dataset() const {
  io::Dataset ds;
  ds.name = "sim-" + config_.name;
  ds.kind = "sim";
  ds.path = "sim:" + config_.name;
  ds.source = make_source();
  ds.rig = rig_;
  ds.ground_truth = ground_truth_;
  return ds;
}

void Simulation::write_euroc(const std::string& dir, bool hide_ground_truth) const {
  fs::create_directories(dir);
  io::EurocWriter writer(dir, rig_);
  for (const SynthImuSample& s : imu_) writer.add_imu(io::ImuSample{s.t, s.gyro, s.accel});
  for (std::size_t k = 0; k < image_times_.size(); ++k)
    for (int c = 0; c < camera_count(); ++c) writer.add_image(c, image_stamp(k), render_image(k, c));
  if (hide_ground_truth) {
    writer.close();
    const fs::path gt_dir = fs::path(dir) / "groundtruth";
    fs::create_directories(gt_dir);
    io::write_trajectory_csv((gt_dir / "state.csv").string(), ground_truth_);
    io::write_tum((gt_dir / "groundtruth.txt").string(), ground_truth_);
    return;
  }
  writer.write_ground_truth(ground_truth_);
  writer.close();
  io::write_tum((fs::path(dir) / "groundtruth.txt").string(), ground_truth_);
}

}  // namespace rtslam::sim
