#pragma once
// Monocular and inertial-monocular EKF-SLAM on images (paper, sections 3, 4.1 and 4.3): a System built from an
// io::Dataset and YAML options — one robot carrying the dataset's camera 0 (intrinsics, distortion and T_RS from
// the Rig), the active-search / one-point RANSAC image data manager, the policy map manager. The robot is
// constant-velocity (IMU samples ignored) or inertial (slam/robot: inertial): IMU samples drive the prediction, an
// image at t_cam is processed once the IMU covers t_cam + t_d (trajectories are stamped in that IMU clock), and the
// filter starts at the first image with `imu/init_window` seconds of IMU before it (inertial_init.hpp).
// The estimator sees the sensors and their calibration only (a Source and a Rig): the first robot pose is the
// known-landmark set's initial state when there is one (its points then fix scale and frame, see
// known_landmarks.hpp), else the world frame itself — identity for the constant-velocity robot, gravity-aligned with
// the first pose's origin and yaw for the inertial robot — with zero covariance (the gauge). Evaluation aligns the
// estimate to a reference afterwards. Seeded: the same options and data give the same output.
//
// YAML layout (every key optional, unknown keys are errors naming the key; docs/configuration.md):
//   slam:        {seed, robot: constant_velocity|inertial, data_manager: active_search, map_manager: policy,
//                 consistency: none|oc|fej, initial_velocity_std, state_capacity, max_frames, camera, cameras,
//                 rate_hz,
//                 known_landmarks, known_landmarks_convention, overlay_frame, overlay_path}
//   motion:      {sigma_v, sigma_w}                (constant-velocity robot)
//   odometry:    {sigma_p, sigma_theta, k_p, k_theta, rescale, rescale_window, rescale_max_se, rescale_min_z}
//                (odometry robot: wheel-odometry increments drive it)
//   imu:         see inertial_init.hpp             (inertial robot)
//   search:      see strategies::ActiveSearchOptions::from_yaml
//   map_manager: {policy: global|visual_odometry, map_size, reparam_threshold, min_searches_to_judge,
//                 min_match_ratio, min_inlier_ratio, forget_after_frames, forget_unseen_after_frames}
//   health:      see slam/health.hpp               (divergence and lost-tracking detection, recovery)
//   zero_velocity: see strategies/zero_velocity.hpp (updates v = 0 when the IMU and the images say "at rest")
//   planar_motion: see strategies/planar_motion.hpp (a wheeled robot's height and tilt held on its floor's plane)
//   position_sensor, pose_sensor: see strategies/absolute.hpp (GPS-like position, motion-capture pose)
//   camera:      {time_offset: see slam/time_offset.hpp}  (online camera–IMU time offset, inertial robot)
//   simulation:  {preset, duration, camera_time_offset_ms}   (only for runs on the simulator: `rtslam run` without
//                --dataset)
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <yaml-cpp/yaml.h>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/models/robots/constant_velocity.hpp"
#include "rtslam/models/robots/odometry.hpp"
#include "rtslam/models/sensors/pinhole_camera.hpp"
#include "rtslam/pipeline/inertial_init.hpp"
#include "rtslam/slam/health.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/odometry_robot.hpp"
#include "rtslam/slam/time_offset.hpp"
#include "rtslam/strategies/absolute.hpp"
#include "rtslam/strategies/active_search.hpp"
#include "rtslam/strategies/known_association.hpp"
#include "rtslam/strategies/map_policies.hpp"
#include "rtslam/strategies/planar_motion.hpp"
#include "rtslam/strategies/zero_velocity.hpp"

namespace rtslam::pipeline {

struct ImageSlamOptions {
  std::uint64_t seed = 1;
  std::string robot = "constant_velocity";  // a registered robot type (builder.hpp): constant_velocity | inertial |
                                            // odometry
  std::string data_manager = "active_search";  // a registered data manager type (builder.hpp)
  std::string map_manager = "policy";          // a registered map manager type (builder.hpp)
  // none: plain EKF; oc: observability-constrained EKF (filter/state.hpp): the filter tracks the unobservable
  // global translation and rotation, constrains the robot's transition and projects every measurement Jacobian so
  // that the linearized system cannot gain information along them (consistent covariances, MATH.md "Consistency");
  // fej: first-estimate Jacobians (slam::Robot::set_first_estimate_jacobians, the data manager's): the robot's
  // transition along its first estimates, observations linearized at the frame's prediction of the robot and at the
  // first (converged) estimate of Euclidean landmarks.
  std::string consistency = "none";
  double initial_velocity_std = 0.5;  // m/s and rad/s: prior std of v and ω (RT-SLAM)
  int state_capacity = 600;           // covariance rows of the filter storage (>= map_manager.map_size)
  int max_frames = 0;                 // stop after this many image times (0: all; several cameras: each time once)
  int camera = 0;                     // index in the Rig (one camera)
  // Several cameras on the robot (slam/cameras: [0, 1]: stereo EuRoC), each with its own data manager, sharing the
  // map's landmarks; empty: `camera` alone. The first one starts the robot and is the reference of the outputs.
  std::vector<int> cameras;
  double rate_hz = 0.0;               // image rate for image folders without timestamps (0: the dataset's)
  std::string known_landmarks;        // folder of a known-landmark set (known_landmarks.hpp); empty: none
  std::string known_landmarks_convention = "robot";  // that set's state: robot (as is) | scenelib (converted)
  int overlay_frame = -1;             // write a PNG overlay of this image (0-based; -1: none) to overlay_path,
  std::string overlay_path;           // drawn by viz::draw_overlay (the overlay of `rtslam run --overlays`)
  std::string sim_preset = "handheld";  // simulator preset or YAML file, for runs without a dataset
  double sim_duration_s = 0.0;           // simulated seconds (0: the preset's)
  std::optional<double> sim_camera_time_offset_ms;  // the simulated images' camera–IMU offset (default: the preset's)
  models::ConstantVelocityParams motion;
  models::OdometryParams odometry;  // odometry robot (slam/robot: odometry): the increments' noise
  // odometry/rescale: auto (one camera, no absolute sensor: the map's scale kept at the odometry's), on, off;
  // odometry/rescale_window, rescale_max_se, rescale_min_z (slam::OdometryScaleOptions; `enabled` is resolved by
  // the builder)
  std::string odometry_rescale = "auto";
  slam::OdometryScaleOptions odometry_scale;
  InertialOptions imu;
  strategies::ActiveSearchOptions search;
  strategies::KnownAssociationOptions association;  // the known_association data manager's (point data; not in YAML)
  strategies::MapPolicyOptions map;
  slam::HealthOptions health;
  strategies::ZeroVelocityOptions zero_velocity;  // zero-velocity updates at rest (strategies/zero_velocity.hpp)
  strategies::PlanarMotionOptions planar_motion;  // a ground robot held on its plane (strategies/planar_motion.hpp)
  slam::TimeOffsetOptions time_offset;  // camera/time_offset: each camera's t_d estimated online (slam/time_offset.hpp)
  // Absolute sensors on the robot (strategies/absolute.hpp): a GPS-like antenna position, a motion-capture pose.
  strategies::AbsoluteSensorOptions position_sensor;
  strategies::AbsoluteSensorOptions pose_sensor = [] {
    strategies::AbsoluteSensorOptions p;
    p.sigma_m = 0.005;
    return p;
  }();
  void validate() const;
  /// The cameras used: `cameras`, or {camera}.
  std::vector<int> camera_indices() const;
  /// These options for a dataset opened with only camera_indices() streamed (io::DatasetOptions::cameras): its Rig
  /// then holds those cameras as 0, 1, ..., so the indices become those.
  ImageSlamOptions on_selected_cameras() const;
};

/// Reads a configuration file over the defaults; throws IoError/ConfigError naming the file and key.
ImageSlamOptions load_image_slam_config(const std::string& path);
void apply_image_slam_config(const YAML::Node& root, const std::string& where, ImageSlamOptions& options);
YAML::Node to_yaml(const ImageSlamOptions& options);

/// io::DistortionModel → models::CameraIntrinsics of one calibrated camera (throws ConfigError if unsupported).
models::CameraIntrinsics to_intrinsics(const io::CameraCalibration& cam);

struct ImageSlamResult {
  Trajectory estimate;  // T_WR per image, with the 6x6 pose covariance
  std::vector<slam::FrameStats> frames;
  int landmarks_final = 0;
  int landmarks_created = 0;  // every landmark the run added to the map, removed ones included
  int euclidean_final = 0;
  int known_landmarks = 0;                      // known landmarks added at the first frame
  std::vector<int> landmark_ids;                // final map
  std::vector<Eigen::Vector3d> landmark_positions;
  std::vector<Eigen::Matrix3d> landmark_covariances;  // of the position (AHP: through J_p_L)
  std::vector<char> landmark_euclidean;         // 1: a Euclidean point, 0: anchored homogeneous (AHP)
  std::vector<double> landmark_depths;          // distance from the final camera position
  // Health (slam/health.hpp): frames judged lost or diverged, re-initializations, and the verdict of the last frame.
  int frames_lost = 0;
  int frames_diverged = 0;
  int resets = 0;
  int frame_gaps = 0;  // gaps between processed images longer than health/max_frame_gap
  slam::Health final_health = slam::Health::Ok;
  int cameras = 1;  // cameras on the robot (several: the scale is known from their baseline)
  // Odometry robot: whether its map's scale was kept at the odometry's (odometry/rescale), its rescales and the
  // product of their factors.
  bool odometry_rescale = false;
  int odometry_rescales = 0;
  double odometry_rescale_product = 1.0;
  // Inertial runs.
  bool inertial = false;
  std::string inertial_start;                   // InertialStart::describe() of the initialization
  long imu_samples = 0;                         // IMU samples read
  long imu_samples_integrated = 0;              // midpoint steps of the prediction
  long imu_gyro_saturated = 0;                  // samples with a gyro axis at the full scale
  long imu_accel_saturated = 0;                 // samples with an accelerometer axis at the full scale
  int images_before_start = 0;                  // images before the IMU window was complete (not processed)
  int images_not_covered = 0;                   // images after the last IMU sample (not processed)
  Eigen::Vector3d gravity_W = Eigen::Vector3d::Zero();  // final estimates
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
  // Camera–IMU extrinsics (imu/estimate_extrinsics): the calibration and the final estimate with its std
  // ([δp (m) δθ (rad)], right perturbation in S).
  bool extrinsics_estimated = false;
  math::Pose T_RS_calibration, T_RS_estimate;
  Eigen::Matrix<double, 6, 1> T_RS_std = Eigen::Matrix<double, 6, 1>::Zero();
  // Camera–IMU time offset (camera/time_offset) of the reference camera: the one the images were stamped with, and
  // the final estimate t_d + δt_d with its std (s).
  bool time_offset_estimated = false;
  double time_offset_stamped_s = 0.0, time_offset_estimate_s = 0.0, time_offset_std_s = 0.0;
};

/// The simulated sequence of `options.sim_preset` (sim::SimConfig::load) with its noise and motion drawn from
/// `options.seed` and `options.sim_duration_s` when > 0, as an in-memory dataset rendered on the fly.
io::Dataset make_sim_dataset(const ImageSlamOptions& options);

/// What an observer sees after each processed image: the map (estimates, landmarks with their descriptors; the
/// robot's pose is map->robots().front()->pose()), the data manager's report of every visible landmark in that
/// image, the image itself, the frame's statistics and the init grid. Every pointer is valid during the call only:
/// keep what outlives it by copy — except the image, whose cv::Mat may be copied (reference counted, no pixel
/// copy: the sources give every image its own pixels and never write into them; viz::make_report does so).
/// Building it costs nothing (pointers on the stack): the frame loop allocates nothing for an observer.
struct ImageSlamFrame {
  int index = 0;  // processed images before this one (the landmarks' frame_created counts the same)
  TimeNs t = 0;   // image time in the IMU clock (t_cam + t_d)
  const slam::Map* map = nullptr;
  const std::vector<strategies::ActiveSearchDataManager::FrameMatch>* matches = nullptr;
  const cv::Mat* image = nullptr;              // the 8-bit grey image processed (the source's own cv::Mat)
  const slam::FrameStats* stats = nullptr;     // this frame's counts and stage timings (also in result.frames)
  const strategies::InitGrid* grid = nullptr;  // the data manager's init grid as this frame left it
  const StampedPose* pose = nullptr;           // this frame's estimate T_WR (also in result.estimate)
};

/// Image SLAM on a measurement stream, in steps: the System that build_system (builder.hpp) makes from the options
/// and the rig, fed from the stream (the images of slam/camera, stamped t_cam + t_d; IMU samples for inertial
/// robots). step() feeds measurements until the filter has processed at least one more image (one fed image can
/// release several: a visual-inertial start replays its window) and returns false once the stream, max_frames or
/// `stop` ended the run; finish() then returns the result. For Python's stepping and live nodes; run_image_slam is
/// the whole loop.
class ImageSlam {
 public:
  ImageSlam(io::Source& source, const io::Rig& rig, std::string name, const ImageSlamOptions& options);
  ~ImageSlam();
  ImageSlam(const ImageSlam&) = delete;
  ImageSlam& operator=(const ImageSlam&) = delete;
  /// After each image the filter processed (see ImageSlamFrame).
  void set_observer(std::function<void(const ImageSlamFrame&)> observer);
  /// (images taken from the stream, their total or 0 if unknown) after each image taken.
  void set_progress(std::function<void(int, int)> progress);
  bool step(const std::atomic<bool>* stop = nullptr);
  /// What was collected so far (estimate and per-frame statistics grow with each step).
  const ImageSlamResult& result() const;
  slam::System& system();
  /// The final map, estimates and counts; DataError if the robot never started. Call once, at the end.
  ImageSlamResult finish();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// A run that never matched: at least `min_frames` camera frames processed and not one landmark corrected in any of
/// them (a threshold nothing reaches, health off, or a run shorter than the health monitor's grace and lost_after).
/// The estimate is then the prior or the proprioceptive sensors alone; the message says so (empty: the run matched).
std::string never_tracked(const ImageSlamResult& result, int min_frames = 10);

/// Runs the pipeline over a measurement stream and its rig calibration (`name` for messages). `on_frame(done,
/// total)` after each image taken from the stream (total 0 if unknown); `observer` after each image the filter
/// processed. `stop`, when given, is read before each measurement: once true, the run ends there and returns what
/// was processed (as max_frames does; e.g. set by a SIGINT handler).
ImageSlamResult run_image_slam(io::Source& source, const io::Rig& rig, const std::string& name,
                               const ImageSlamOptions& options, const std::function<void(int, int)>& on_frame = {},
                               const std::function<void(const ImageSlamFrame&)>& observer = {},
                               const std::atomic<bool>* stop = nullptr);
/// The same on a dataset's source and rig (its reference trajectory, if any, is for evaluation and is not read).
ImageSlamResult run_image_slam(io::Dataset& dataset, const ImageSlamOptions& options,
                               const std::function<void(int, int)>& on_frame = {},
                               const std::function<void(const ImageSlamFrame&)>& observer = {},
                               const std::atomic<bool>* stop = nullptr);

}  // namespace rtslam::pipeline
