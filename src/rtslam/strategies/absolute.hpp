#pragma once
// The data manager of the absolute sensors (slam/absolute_sensor.hpp): a GPS-like position of an antenna on the
// robot, or a motion-capture pose of a marker body on it, each corrects the robot pose in one EKF update
// (models/sensors/absolute.hpp: innovation and analytic Jacobians through the lever arm), gated by its
// Mahalanobis distance; applied and rejected updates are counted in FrameStats (absolute_updates,
// absolute_rejected).
//
// The world frame. The sensor measures in its own frame G (ENU, the motion-capture room, the simulator's world),
// and the estimator's world frame W must be G: the trajectories it writes are then comparable with the sensor's
// frame without any alignment. The robot itself starts in its own gauge (the first pose: identity, or
// gravity-aligned with the first pose's origin and yaw for the inertial robot), so with `world: align` (default)
// the first fixes tell where that frame lies in G and the whole map is moved there once
// (slam::change_world_frame), with the uncertainty of that alignment added to it:
//  - pose sensor: at the first fix, T_GW = z h⁻¹ (z = T_GM measured, h = T_WM predicted), the whole rotation (the
//    inertial robot's frame is gravity-aligned only up to its gravity state, which turns with the map). Uncertainty:
//    the fix's.
//  - position sensor (inertial robot only: gravity gives roll and pitch, the fixes give yaw and translation): every
//    fix is collected with the predicted antenna position (in the start frame W0), and at each one the map is moved
//    rigidly (no uncertainty claimed) onto the least-squares yaw and translation of all fixes so far: translation
//    only (the robot's own yaw) until `align_min_fixes` fixes whose horizontal spread gives the yaw to 45 deg, then
//    yaw and translation in closed form (2-D Procrustes about the centroids, σ_ψ = σ / √Σ|h_k − h̄|²_xy). Once
//    σ_ψ ≤ `align_yaw_std_deg` the filter takes over: the last move adds σ²/N on the translation and σ_ψ² on the
//    yaw to the map, and from then on every fix corrects the filter, which keeps refining them. The hand-over waits
//    for a small σ_ψ: the filter corrects a yaw error linearly, the rigid moves before it are exact (a hand-over at
//    10 deg on the simulator's hall was followed by a divergence verdict of the camera NIS 1.6 s later).
//  Until the hand-over, fixes do not correct the filter (the moves before it allocate: warm-up). With `world: start`
//  the robot's start frame is taken as G (a sensor zeroed where the robot starts) and every fix corrects from the
//  first.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/yaml.hpp"
#include "rtslam/slam/absolute_sensor.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/world_frame.hpp"

namespace rtslam::strategies {

struct AbsoluteSensorOptions {
  bool enabled = false;
  double sigma_m = 0.5;            // m: position std per axis of a fix without its own covariance
  double sigma_deg = 1.0;          // deg: attitude std per axis (pose sensor)
  Eigen::Vector3d lever_arm = Eigen::Vector3d::Zero();     // m: p_RA (antenna) or p_RM (marker body) in R
  Eigen::Vector3d rotation_deg = Eigen::Vector3d::Zero();  // deg: R_RM as a rotation vector (pose sensor)
  double gate = 0.0;               // Mahalanobis² gate (0: χ² 99.9 % of the sensor's dof: 16.27 position, 22.46 pose)
  std::string world = "align";     // align | start (header comment)
  double align_yaw_std_deg = 3.0;   // position sensor: hand over to the filter once the fixes give the yaw to this std
  int align_min_fixes = 10;         // position sensor: fixes needed before aligning
  /// T_RS of the sensor: (Exp(rotation), lever_arm) (rotation: pose sensor only).
  math::Pose T_RS() const;
  /// The gate in use for a sensor of `dof` measurement rows.
  double gate_for(int dof) const;
  void validate(const std::string& where) const;
};

/// position_sensor: {enabled, sigma, lever_arm, gate, world, align_yaw_std_deg, align_min_fixes};
/// pose_sensor: {enabled, sigma, sigma_deg, lever_arm, rotation_deg, gate, world}. `where`: the section's name.
void read_absolute_sensor(YamlMap section, AbsoluteSensorOptions& o, bool pose);
YAML::Node absolute_sensor_to_yaml(const AbsoluteSensorOptions& o, bool pose);

class AbsoluteDataManager final : public slam::DataManager {
 public:
  /// `gravity_aligned`: the robot's world frame is gravity-aligned (inertial robot): only yaw and translation are
  /// aligned, and a position sensor can align at all.
  AbsoluteDataManager(AbsoluteSensorOptions options, bool gravity_aligned);
  void process(slam::Map& map, slam::Sensor& sensor, const slam::RawData& raw, long frame,
               slam::FrameStats& stats) override;
  std::string name() const override { return "absolute"; }

  bool aligned() const { return aligned_; }
  /// The change that aligned the map (header comment), once aligned by the fixes.
  const slam::WorldChange& alignment() const { return alignment_; }
  TimeNs aligned_at() const { return aligned_at_; }
  long updates() const { return updates_; }
  long rejected() const { return rejected_; }
  /// NIS of the last fix (yᵀ S⁻¹ y), 0 before the first correction.
  double last_nis() const { return last_nis_; }

 private:
  void align_position(slam::Map& map, const Eigen::Vector3d& z, const Eigen::Vector3d& h, double sigma, TimeNs t);
  void align_pose(slam::Map& map, const math::Pose& z, const math::Pose& h, const Eigen::Matrix<double, 6, 6>& R,
                  TimeNs t);
  void apply(slam::Map& map, const slam::WorldChange& change);

  AbsoluteSensorOptions o_;
  bool gravity_aligned_;
  bool aligned_ = false;
  math::Pose T_moved_;  // position sensor before the hand-over: the rigid move applied so far (x = T_moved x_W0)
  slam::WorldChange alignment_;
  TimeNs aligned_at_ = 0;
  std::vector<Eigen::Vector3d> fixes_, predicted_;  // position alignment: z_k and h_k in the start frame W0
  Eigen::MatrixXd H_, R_;
  Eigen::VectorXd y_;
  long updates_ = 0, rejected_ = 0;
  double last_nis_ = 0.0;
};

}  // namespace rtslam::strategies
