#pragma once
// A complete simulated sequence: a world, a trajectory of the robot (IMU) frame, a camera + IMU rig, and the
// streams they produce: images rendered on demand at the camera rate, IMU samples at the IMU rate, and the exact
// ground truth (pose, velocity, biases) at every IMU sample. It can be streamed in memory (io::Source, for
// `rtslam run` with no dataset) or written as an EuRoC/ASL folder plus groundtruth.txt (TUM).
//
// Presets bundle a world, a trajectory and a rig (SimConfig::preset): "handheld" (room, hand-held motion, EuRoC
// cam0 at 20 Hz, ADIS16448 IMU at 200 Hz, 30 s), "high-dynamic" (room, the RT-SLAM paper's extreme profile,
// camera at 50 Hz, 45 s), "hall" (a larger hall with random boxes, hand-held, 30 s). YAML format in
// docs/simulator.md and config/sim/*.yaml.
//
// Recorded mode (`trajectory: recorded:DIR`, DIR an EuRoC/ASL folder): the robot follows the folder's recorded state
// trajectory (state_groundtruth_estimate0/data.csv) exactly (RecordedTrajectory, no smoothing), the IMU stream is the
// folder's RECORDED imu0/data.csv (nothing synthesized: real noise, vibration, biases), images are rendered at the
// recorded state timestamps (EuRoC writes its state at the camera timestamps) with the folder's calibrations
// (cam0, and cam1 with `stereo`), and the ground truth is the recorded state. `start_offset` and `duration` cut a
// window of the recording.
//
// Seeds: `seed` redraws every noise source (pixel noise, IMU white noise, bias walks, initial biases);
// `trajectory_seed` (default: = seed) draws the shape of the handheld/high-dynamic motion. The world has its own
// `world.seed` (textures), so runs with different seeds see the same room.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/calibration.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/source.hpp"
#include "rtslam/models/sensors/pinhole_camera.hpp"
#include "rtslam/sim/absolute.hpp"
#include "rtslam/sim/imu.hpp"
#include "rtslam/sim/odometry.hpp"
#include "rtslam/sim/renderer.hpp"
#include "rtslam/sim/trajectory.hpp"
#include "rtslam/sim/world.hpp"

namespace rtslam::sim {

struct SimConfig {
  std::string name = "handheld";
  std::uint64_t seed = 1;
  std::optional<std::uint64_t> trajectory_seed;  // default: seed
  double duration_s = 30.0;
  double start_time_s = 1.0;         // timestamp of the first sample for synthetic trajectories
  std::string trajectory = "handheld";  // handheld | high-dynamic | ground | follow:FILE | recorded:DIR
  double ground_speed_mps = 0.5;     // ground: mean speed of the laps (m/s)
  double start_offset_s = 0.0;       // follow/recorded: start this many seconds after the recording's first pose
  bool stereo = false;               // also render camera 1 (camera1; a recorded folder's cam1)
  double follow_knot_spacing_s = 0.05;
  WorldConfig world = WorldConfig::preset("room");
  io::CameraCalibration camera = euroc_cam0();
  io::CameraCalibration camera1 = euroc_cam1();
  RenderOptions render;
  // Camera–IMU time offset of the data (`camera.time_offset_ms`): an image captured at t (IMU clock) is stamped
  // t − t_d, so that t_imu = t_cam + t_d as in the calibrations; the rig still says t_d = 0 (an unknown offset).
  double camera_time_offset_s = 0.0;
  bool imu_enabled = true;
  ImuSynthOptions imu;
  OdometrySynthOptions odometry;  // wheel odometry of the robot frame (odometry.hpp; off unless configured)
  // Absolute sensors measured from the ground truth (sim/absolute.hpp): a GPS-like position, a motion-capture pose.
  AbsoluteSimOptions gps;
  AbsoluteSimOptions mocap = [] {
    AbsoluteSimOptions m;
    m.rate_hz = 100.0;
    m.sigma_m = 0.001;
    m.sigma_deg = 0.1;
    return m;
  }();

  /// EuRoC MAV cam0 (mav0/cam0/sensor.yaml): 752x480, 20 Hz, radial-tangential, T_BS as T_RS.
  static io::CameraCalibration euroc_cam0();
  /// EuRoC MAV cam1 (mav0/cam1/sensor.yaml): the right camera of the stereo pair, 11 cm from cam0.
  static io::CameraCalibration euroc_cam1();
  bool recorded() const { return trajectory.rfind("recorded:", 0) == 0; }
  /// Built-in presets (see the header comment); ConfigError for an unknown name.
  static SimConfig preset(const std::string& name);
  static std::vector<std::string> preset_names();
  /// A preset name or a YAML file (strict; keys documented in docs/simulator.md). Relative paths inside the file
  /// (world file, calibration, follow:FILE) are resolved against the file's folder.
  static SimConfig load(const std::string& name_or_file);
  /// Reads a preset mapping on top of `base`.
  static SimConfig from_yaml(YamlMap& map, SimConfig base, const std::string& dir);
  void validate() const;
};

/// Pinhole intrinsics of an io calibration in the models' types (ConfigError for a model sim cannot render).
models::CameraIntrinsics to_intrinsics(const io::CameraCalibration& cam);

class Simulation : public std::enable_shared_from_this<Simulation> {
 public:
  /// Builds everything (textures, ray table, IMU samples, ground truth). For follow:FILE the room is grown and
  /// obstacles on the path removed; for synthetic trajectories a path through an obstacle is a ConfigError.
  static std::shared_ptr<const Simulation> create(const SimConfig& config);

  const SimConfig& config() const { return config_; }
  const World& world() const { return *world_; }
  const ContinuousTrajectory& trajectory() const { return *trajectory_; }
  const models::PinholeCamera& camera(int c = 0) const { return *cameras_.at(static_cast<std::size_t>(c)); }
  int camera_count() const { return static_cast<int>(cameras_.size()); }
  /// The rig: camera 0 (and 1 with stereo) with T_RS, the IMU (noise densities, T_RS = identity) when enabled,
  /// t_d = 0.
  const io::Rig& rig() const { return rig_; }
  /// Image times (every camera renders at each): the true capture times, in the IMU clock.
  const std::vector<TimeNs>& image_times() const { return image_times_; }
  /// The timestamp image k carries in the streams: its capture time less the camera–IMU offset.
  TimeNs image_stamp(std::size_t k) const { return image_times_[k] - time_offset_; }
  /// IMU samples: synthesized (with the true biases), or recorded (biases unknown: zero).
  const std::vector<SynthImuSample>& imu_samples() const { return imu_; }
  /// Odometry readings (config().odometry.enabled; synthetic trajectories only), streamed by make_source (not
  /// written by write_euroc).
  const std::vector<SynthOdometry>& odometry() const { return odometry_; }
  /// Ground truth of R at every IMU sample (at every image without IMU; at the recorded states in recorded mode):
  /// p, q, v, gyro and accel biases.
  const Trajectory& ground_truth() const { return ground_truth_; }
  /// Absolute fixes (empty unless gps / mocap is enabled), in the world frame W.
  const std::vector<io::PositionSample>& gps_fixes() const { return gps_; }
  const std::vector<io::PoseSample>& mocap_fixes() const { return mocap_; }
  /// T_WC of camera c at time t (T_WR(t) * T_RS).
  math::Pose camera_pose(TimeNs t, int c = 0) const;
  /// Renders image k of camera c (deterministic: its noise seed derives from (seed, k, c)).
  cv::Mat render_image(std::size_t k, int c = 0) const;

  /// An in-memory stream (IMU first at equal timestamps, then odometry, then images, GPS fixes, mocap poses); it keeps
  /// this simulation alive.
  std::unique_ptr<io::Source> make_source() const;
  /// The stream, rig and ground truth as an io::Dataset (kind "sim"), for `rtslam run` with no dataset.
  io::Dataset make_dataset() const;
  /// Writes DIR/mav0/{cam0[, cam1], imu0, state_groundtruth_estimate0} (EuRoC ASL) and DIR/groundtruth.txt (TUM),
  /// using `threads` rendering threads per frame. Identical bytes for identical configs. With `hide_ground_truth`
  /// the ground truth goes to DIR/groundtruth/ only (state.csv, EuRoC state CSV, and groundtruth.txt): the mav0
  /// folder then holds what a user's recording holds, sensors and calibration, for runs that must not see it.
  void write_euroc(const std::string& dir, bool hide_ground_truth = false) const;

 private:
  explicit Simulation(const SimConfig& config);

  SimConfig config_;
  std::unique_ptr<ContinuousTrajectory> trajectory_;
  std::unique_ptr<World> world_;
  std::vector<std::unique_ptr<models::PinholeCamera>> cameras_;
  std::vector<std::unique_ptr<Renderer>> renderers_;
  std::vector<math::Pose> T_RS_;
  io::Rig rig_;
  std::vector<TimeNs> image_times_;
  TimeNs time_offset_ = 0;
  std::vector<SynthImuSample> imu_;
  std::vector<SynthOdometry> odometry_;
  Trajectory ground_truth_;
  std::vector<io::PositionSample> gps_;
  std::vector<io::PoseSample> mocap_;
};

/// Mixes a seed with a stream id and an index (splitmix64): independent generators per noise source and frame.
std::uint64_t mix_seed(std::uint64_t seed, std::uint64_t stream, std::uint64_t index = 0);

}  // namespace rtslam::sim
