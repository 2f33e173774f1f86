#pragma once
// The points demo's simulation (the walking skeleton, pipeline/point_demo.hpp): a room whose walls, floor and ceiling
// carry a few hundred 3D points, the EuRoC cam0 camera (intrinsics, distortion and T_RS) on a hand-held robot body
// moving along the `handheld` trajectory, and per frame the pixel measurements of the points in view with Gaussian
// noise and their true identities. The truth (points and poses) stays here: the SLAM side is given the measurements
// and a start pose, and the caller scores the run against groundtruth() afterwards.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/random.hpp"
#include "rtslam/core/time.hpp"
#include "rtslam/core/trajectory.hpp"
#include "rtslam/io/calibration.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/models/sensors/pinhole_camera.hpp"
#include "rtslam/sim/trajectory.hpp"

namespace rtslam::sim {

struct PointSceneOptions {
  std::uint64_t seed = 1;                      // points, trajectory and pixel noise
  double duration_s = 30.0;
  double rate_hz = 30.0;                       // frames per second
  int n_points = 500;
  Eigen::Vector3d room_min{-4.0, -3.0, 0.0};  // m, W (z up)
  Eigen::Vector3d room_max{4.0, 3.0, 3.0};
  double sigma_px = 1.0;                       // pixel noise (std, px)
  double margin_px = 8.0;                      // measurements closer than this to the image border are not made
  /// ConfigError naming `where`, the key and its bounds.
  void validate(const std::string& where) const;
};

/// One measured image point with its true identity (the point's index).
struct ScenePoint {
  int id = 0;
  Eigen::Vector2d z = Eigen::Vector2d::Zero();
};

class PointScene {
 public:
  explicit PointScene(const PointSceneOptions& options);

  /// The camera as a calibration: EuRoC cam0 (SimConfig::euroc_cam0) at the scene's frame rate.
  const io::CameraCalibration& camera() const { return camera_; }
  int frame_count() const { return n_frames_; }
  TimeNs frame_time(int k) const;
  /// T_WR at the first frame: the start pose a user gives the filter (its gauge).
  math::Pose start_pose() const;
  /// The measurements of frame k into `out` (cleared first). Frames are measured in order 0, 1, ..., each once:
  /// the pixel noise is drawn in that order, so that a seed gives one sequence.
  void measure(int k, std::vector<ScenePoint>& out);
  /// The true T_WR (and v_WR) at every frame, for scoring a run afterwards.
  Trajectory groundtruth() const;
  /// The true points (W), indexed by the measurements' ids.
  const std::vector<Eigen::Vector3d>& points() const { return points_; }

 private:
  PointSceneOptions options_;
  Rng rng_;
  std::vector<Eigen::Vector3d> points_;
  std::unique_ptr<ContinuousTrajectory> trajectory_;
  io::CameraCalibration camera_;
  models::PinholeCamera model_;
  math::Pose T_RS_;
  int n_frames_ = 0;
  int next_frame_ = 0;
};

}  // namespace rtslam::sim
