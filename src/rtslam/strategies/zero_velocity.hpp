#pragma once
// Zero-velocity updates (ZUPT): when the IMU and the images both say the robot is at rest, the filter is told so — a
// pseudo-measurement v_WR = 0 (and, for the constant-velocity robot, ω = 0) with a small std — which stops the slow
// drift a filter accumulates while standing (integrated accelerometer noise and bias; OpenVINS's zero-velocity update
// plays the same part). At rest means, over the last `window` s:
//   - the IMU: the spread of the gyro and of the accelerometer readings averaged over 25 ms blocks below thresholds
//     (a vibrating MAV on its legs passes — the block means average the rotors' vibration out —, a moving one does
//     not), and
//   - the images: the median displacement of the landmarks matched in this frame and the previous one below
//     `max_disparity_px` (the IMU alone cannot tell a vibrating rest from slow motion).
// The detector needs both; robots without inputs are judged by the images alone.
#include <limits>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/yaml.hpp"
#include "rtslam/slam/system.hpp"
#include "rtslam/strategies/active_search.hpp"

namespace rtslam::strategies {

struct ZeroVelocityOptions {
  bool enabled = false;
  double window_s = 0.5;           // IMU window judged (s)
  double max_gyro_std = 0.1;       // rad/s, norm of the per-axis std over the window
  double max_accel_std = 1.6;      // m/s², idem
  double max_disparity_px = 0.3;   // median image displacement of the matched landmarks since the previous frame
  int min_matches = 10;            // landmarks matched in both frames needed to judge the images
  double velocity_std = 0.002;     // m/s (and rad/s): the pseudo-measurement's std
  void validate() const;
};

/// zero_velocity: {enabled, window, max_gyro_std, max_accel_std, max_disparity_px, min_matches, velocity_std}.
void read_zero_velocity(YamlMap section, ZeroVelocityOptions& o);
YAML::Node zero_velocity_to_yaml(const ZeroVelocityOptions& o);

/// One hook per System; each robot to be held at rest is added with its own options (a robot not added is left
/// alone). The image test compares each camera's frame with that camera's previous one; the robot's verdict is the
/// latest judged by any of its cameras (a camera that now sees motion ends a rest another one saw earlier). The update
/// is applied at most once per robot and time (a stereo pair's two images are two steps of one time: telling the
/// filter twice would divide the std by √2). As an Observer (System::add_observer) it forgets a robot's verdict and
/// its cameras' previous frames when the robot restarts.
class ZeroVelocityUpdater final : public slam::StepHook, public slam::Observer {
 public:
  /// Updates `robot` at rest with `options` (validated; `enabled` is not looked at). Before the run. ConfigError
  /// for a robot without rate states (Robot::rest_rows() = 0) or added twice.
  void add_robot(const slam::Robot& robot, const ZeroVelocityOptions& options);
  void after_step(slam::Map& map, slam::Robot& robot, const slam::Sensor& sensor, const slam::RawData& raw,
                  const RingBuffer<slam::ImuData>& inputs, slam::FrameStats& stats) override;
  /// What after_step does with one camera's image at time t once its matches are known (`matches`: the frame's
  /// visible observations, ActiveSearchDataManager::last_frame()).
  void after_image(slam::Map& map, slam::Robot& robot, int sensor_id, TimeNs t,
                   std::span<const ActiveSearchDataManager::FrameMatch> matches,
                   const RingBuffer<slam::ImuData>& inputs, slam::FrameStats& stats);
  void on_step(const slam::StepReport& /*step*/) override {}
  /// A robot (re)started: its verdict, its last update's time and its cameras' previous frames are forgotten.
  void on_start(const slam::Robot& robot, const slam::RobotStart& start) override;
  long updates() const { return updates_; }
  /// Updates the filter refused (the first is logged as a warning).
  long refused() const { return refused_; }
  /// The image test alone: the median displacement (px) of the landmarks matched now and in the sensor's previous
  /// frame, or a negative value when fewer than min_matches are.
  double last_disparity_px() const { return disparity_; }

 private:
  // The images' latest verdict and its time, kept through frames with too few matches to judge for at most
  // `window` s.
  struct Verdict {
    bool still = false;
    TimeNs t = 0;
  };
  struct Held {
    const slam::Robot* robot = nullptr;
    ZeroVelocityOptions options;
    Verdict verdict;
    TimeNs last_t = std::numeric_limits<TimeNs>::min();  // the time of its latest update
    Eigen::MatrixXd H, R;
    Eigen::VectorXd y;
  };
  bool imu_at_rest(const ZeroVelocityOptions& o, const RingBuffer<slam::ImuData>& inputs, TimeNs t) const;

  std::vector<Held> held_;
  // Per sensor id: the landmarks matched in its previous frame and their pixels, sorted by id (bounded by the
  // matches of a frame, whatever the ids grow to over a long run).
  struct Matched {
    int id;
    Eigen::Vector2d z;
  };
  std::vector<std::vector<Matched>> last_z_;
  std::vector<double> displacements_;
  double disparity_ = -1.0;
  long updates_ = 0, refused_ = 0;
};

}  // namespace rtslam::strategies
