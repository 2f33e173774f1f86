#pragma once
// The robot starters of image SLAM (slam::RobotStarter): how the System puts a robot into the map.
//  - PoseStarter (constant-velocity robot): at the first image, at the world origin (the gauge: zero pose
//    covariance, the velocity prior slam/initial_velocity_std), or at a known-landmark set's initial state (whose
//    points it then adds: they fix scale and frame), or at a given state (the points demo's start pose).
//  - InertialStarter (inertial robot): the visual-inertial start (vi_init.hpp) over a sliding window of images and
//    the IMU, falling back to the IMU-only start (inertial_init.hpp) after vi_init/max_wait of failures; with
//    vi_init off, the IMU-only start at the first image with imu/init_window seconds of IMU before it.
// Both start again the same way after a health reset (the System re-anchors the state in the world frame).
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "rtslam/math/rotation.hpp"
#include "rtslam/models/sensors/pinhole_camera.hpp"
#include "rtslam/pipeline/inertial_init.hpp"
#include "rtslam/pipeline/known_landmarks.hpp"
#include "rtslam/slam/sensor.hpp"
#include "rtslam/slam/system.hpp"
#include "rtslam/strategies/active_search.hpp"

namespace rtslam::pipeline {

/// An image datum that owns its pixels (the source's cv::Mat, reference counted: no copy).
struct MatImage final : strategies::RawImage {
  cv::Mat mat;
  // The last image of its time (several cameras: the others of the same time come first): the session's observers
  // see a time once, after its last image.
  bool closes_time = true;
  void set(TimeNs time, int sensor, cv::Mat m) {
    t = time;
    sensor_id = sensor;
    mat = std::move(m);
    closes_time = true;
    image = vision::ImageView{mat.data, mat.cols, mat.rows, static_cast<int>(mat.step[0])};
  }
  void release() override {
    mat.release();
    image = vision::ImageView{};
  }
};

class PoseStarter final : public slam::RobotStarter {
 public:
  /// `initial`: the state to start at (13: [p q v ω]) with `initial_cov` (12×12), or of another robot [p q ...]
  /// (the odometry robot's [p q]) with its `initial_cov` (required); else the origin with the velocity prior. `known`: a known-landmark set whose initial state is the start and whose points are added.
  PoseStarter(double initial_velocity_std, std::optional<KnownLandmarkSet> known,
              std::optional<Eigen::VectorXd> initial = std::nullopt, Eigen::MatrixXd initial_cov = {});
  std::optional<slam::RobotStart> offer(const slam::RawData& datum, const RingBuffer<slam::ImuData>& inputs) override;
  void started(slam::Map& map, slam::Robot& robot, bool first) override;
  int known_landmarks_added() const { return known_added_; }

 private:
  Eigen::VectorXd x0_;
  Eigen::MatrixXd P0_;
  std::optional<KnownLandmarkSet> known_;
  int known_added_ = 0;
};

class InertialStarter final : public slam::RobotStarter {
 public:
  /// `camera`: the camera whose images the start uses (with several, the others' images before the start are
  /// dropped); `dm`: its data manager, given the scene depth of a visual-inertial start (may be null).
  InertialStarter(const InertialOptions& options, const slam::Sensor& camera, const models::CameraIntrinsics& intrinsics,
                  const math::Pose& T_RS, strategies::ActiveSearchDataManager* dm);
  std::optional<slam::RobotStart> offer(const slam::RawData& datum, const RingBuffer<slam::ImuData>& inputs) override;
  void started(slam::Map& map, slam::Robot& robot, bool first) override;
  void restart() override;
  int skipped() const override { return skipped_; }
  std::string waiting_for() const override;

 private:
  std::optional<slam::RobotStart> imu_only(TimeNs t, const RingBuffer<slam::ImuData>& inputs, std::string prefix);
  std::optional<slam::RobotStart> try_visual_inertial(const RingBuffer<slam::ImuData>& inputs);

  InertialOptions o_;
  const slam::Sensor& sensor_;
  models::PinholeCamera camera_;
  math::Pose T_RS_;
  strategies::ActiveSearchDataManager* dm_;
  struct WindowImage {
    TimeNs t = 0;
    cv::Mat image;
  };
  std::vector<WindowImage> window_;           // the visual-inertial start's images
  std::vector<strategies::ViInitFrame> views_;  // the same, as the start takes them
  int sensor_id_ = -1;
  TimeNs first_image_t_ = -1;                 // of the current start attempt
  std::optional<double> depth_hint_;          // of the last visual-inertial start, for the data manager
  std::vector<std::unique_ptr<MatImage>> replay_;  // the window's images, as data to process after a start
  const slam::RawData* offered_ = nullptr;
  int skipped_ = 0;
  // Why the last offer did not start the robot, formatted by waiting_for() only (nothing is formatted per frame).
  enum class Wait { Nothing, ImuWindow, ViWindow, ViAccepted };
  Wait wait_ = Wait::Nothing;
  TimeNs wait_imu_first_ = -1;  // ImuWindow: the oldest IMU sample held (-1: none)
  std::string wait_reason_;     // ViAccepted: why the last window failed
};

/// The recent IMU samples as the start functions take them.
std::vector<strategies::ImuWindowSample> imu_window(const RingBuffer<slam::ImuData>& inputs);

}  // namespace rtslam::pipeline
