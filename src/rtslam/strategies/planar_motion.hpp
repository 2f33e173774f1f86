#pragma once
// Planar motion (`planar_motion`): a robot that drives on a flat floor keeps its height and its up axis. Told so
// after every image — a pseudo-measurement of the robot's height above the plane it started on and of the tilt of
// its up axis off the plane's normal, both 0 with a std that stands for the floor's unevenness — the filter holds
// the two tilt angles and the height that nothing else measures when a wheeled robot has one camera and wheel
// odometry and no IMU (no gravity reference: only the start pose and the first landmarks' correlations hold them;
// docs/odometry-scale.md, the ground preset's attitude failures). The planar-motion constraint of wheeled VIO
// (Wu et al., "VINS on wheels", ICRA 2017) as a per-image EKF update.
//
// The plane is the one the robot is on at its first image: normal n = R_WR · up (up: the robot-frame axis normal
// to the floor, `up`), through its position p then. With t₁, t₂ an orthonormal basis of the plane,
//   h(x) = [ nᵀ(p − p₀),  t₁ᵀ R_WR up,  t₂ᵀ R_WR up ] = 0,   R = diag(height_std², tilt_std², tilt_std²),
// and, for the right perturbation R_WR ← R_WR Exp(δθ) (MATH.md), ∂(tᵢᵀ R up)/∂δθ = −tᵢᵀ R_WR [up]×.
// Any robot whose block starts with [p q] (all of rtslam's) can use it. The plane stays through the health monitor's
// re-initializations (they keep the world frame). The odometry robot's rescales scale about its start, which is on the
// plane; after a re-initialization they scale about the restart's position, off the plane by the estimate's height
// error then (centimetres at most), whose (1 − c) share each rescale by c moves the plane's heights by and the update
// then pulls back. Not with the observability-constrained filter (slam/consistency: oc), whose basis keeps the world's
// tilt and height unobservable, which this measures, nor with an absolute sensor that aligns (moves) the world frame
// (ImageSlamOptions::validate refuses both).
#include <limits>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/yaml.hpp"
#include "rtslam/slam/system.hpp"

namespace rtslam::strategies {

struct PlanarMotionOptions {
  bool enabled = false;
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  // robot-frame axis normal to the floor (normalized on use)
  double height_std = 0.02;                       // m: the floor's unevenness and the suspension's travel
  double tilt_std = 0.02;                         // rad (~1.1°): the robot's pitch and roll on that floor
  /// ConfigError naming the key (planar_motion: up, height_std, tilt_std) out of range.
  void validate() const;
};

/// planar_motion: {enabled, up: [x, y, z], height_std, tilt_std}.
void read_planar_motion(YamlMap section, PlanarMotionOptions& o);
YAML::Node planar_motion_to_yaml(const PlanarMotionOptions& o);

/// The measurement's value and Jacobian for one robot pose against one plane (normal n, unit; through p0).
/// h (3) as in the file comment; H (3 × 6) over the robot's [δp δθ] tangent columns.
void planar_motion_measurement(const Eigen::Vector3d& p, const Eigen::Matrix3d& R_WR, const Eigen::Vector3d& up,
                               const Eigen::Vector3d& n, const Eigen::Vector3d& p0, Eigen::Vector3d& h,
                               Eigen::Matrix<double, 3, 6>& H);

/// One hook per System; each robot that should be held on its plane is added with its own options (a robot not
/// added is left alone). Acts on camera images only (not on absolute fixes), once per robot and time (a stereo
/// pair's two images are two steps of one time: telling the filter twice would halve the stds). As an Observer
/// (System::add_observer) it tells a restarted robot again at the restart's time (the plane itself is kept).
class PlanarMotionUpdater final : public slam::StepHook, public slam::Observer {
 public:
  /// Holds `robot` on its plane with `options` (validated; `enabled` is not looked at). Before the run.
  void add_robot(const slam::Robot& robot, const PlanarMotionOptions& options);
  void after_step(slam::Map& map, slam::Robot& robot, const slam::Sensor& sensor, const slam::RawData& raw,
                  const RingBuffer<slam::ImuData>& inputs, slam::FrameStats& stats) override;
  void on_step(const slam::StepReport& /*step*/) override {}
  /// A robot (re)started: its next image is told the plane even at the time of its last update.
  void on_start(const slam::Robot& robot, const slam::RobotStart& start) override;
  long updates() const { return updates_; }
  /// Updates the filter refused (the first is logged as a warning).
  long refused() const { return refused_; }
  /// The plane a robot is held on (its normal and a point on it, world frame), once its first image is past.
  struct Plane {
    Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
    Eigen::Vector3d p0 = Eigen::Vector3d::Zero();
  };
  std::optional<Plane> plane(const slam::Robot& robot) const;

 private:
  struct Held {
    const slam::Robot* robot = nullptr;
    PlanarMotionOptions options;
    Eigen::Vector3d up;  // options.up normalized
    std::optional<Plane> plane;
    TimeNs last_t = std::numeric_limits<TimeNs>::min();  // the time of its latest update
    Eigen::MatrixXd H, R;
    Eigen::VectorXd y;
  };
  std::vector<Held> held_;
  long updates_ = 0, refused_ = 0;
};

}  // namespace rtslam::strategies
