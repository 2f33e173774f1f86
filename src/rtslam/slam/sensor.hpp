#pragma once
// Sensors hang off their robot by T_RS: fixed (the calibration), or estimated as a block of the map, [p_RS q_RS]
// with tangent [δp δθ] (the paper's "sensors belong to the map": camera–IMU extrinsics refined online). A point
// sensor projects a landmark's homogeneous direction h_S (in S) to a measurement.
//
// Time offset (Li & Mourikis 2014, OpenVINS): a sensor may own a 1-row block δt_d (s), the residual of its clock
// offset around the one its data were stamped with (data come stamped t_cam + t_d in the robot's clock; the true
// capture time is that plus δt_d). The System predicts the robot to the datum's time plus the current estimate
// (time_shift: δt_d of the mean, clamped to ±max), records that shift (applied_time_shift), and the sensor's pose
// is the robot's moved along its pose rate xi = [v_W; ω_R] (Robot::pose_rate) by what the state says beyond it:
//   T_WR' = T_WR ⊞ s·xi = (p + s v, q ⊗ Exp(s ω)),  s = δt_d − applied,   T_WS = T_WR' T_RS,
// so ∂T_WS/∂δt_d = J_TWS_TWR' xi (exact in δt_d, at the xi of the prediction) and, at s = 0 where every frame is
// linearized, the observation's Jacobian wrt δt_d is H_pose xi (the landmark's pixel velocity). The dependence of
// T_WR' on v and the gyro bias through s is neglected (zero at s = 0).
#include <memory>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "rtslam/core/time.hpp"
#include "rtslam/filter/state.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/models/sensors/pinhole_camera.hpp"
#include "rtslam/slam/fwd.hpp"

namespace rtslam::slam {

class Sensor {
 public:
  virtual ~Sensor();
  Sensor(const Sensor&) = delete;
  Sensor& operator=(const Sensor&) = delete;

  int id() const { return id_; }
  const std::string& name() const { return name_; }
  Robot& robot() const { return *robot_; }
  /// The calibrated (prior) T_RS.
  const math::Pose& T_RS() const { return T_RS_; }
  /// T_RS in `mean` when estimated, else the calibration.
  math::Pose T_RS(const Eigen::VectorXd& mean) const;
  /// T_WS = T_WR T_RS for the robot pose (and the extrinsics, when estimated) in `mean`, moved along the robot's
  /// pose rate by the time offset beyond the applied shift when it is estimated (header comment); J_TWS_TWR and
  /// J_TWS_TRS (6x6, [δp δθ]) if requested (J_TWS_TRS only for an estimated T_RS), J_TWS_td (6x1, per second) only
  /// for an estimated time offset.
  math::Pose pose_in_world(const Eigen::VectorXd& mean, Eigen::Matrix<double, 6, 6>* J_TWS_TWR = nullptr,
                           Eigen::Matrix<double, 6, 6>* J_TWS_TRS = nullptr,
                           Eigen::Matrix<double, 6, 1>* J_TWS_td = nullptr) const;

  /// Asks for T_RS to be estimated, starting from the calibration with this [δp δθ] prior covariance. Must be
  /// called before the robot joins a map (the block is created then).
  void estimate_extrinsics(const Eigen::Matrix<double, 6, 6>& prior_cov);
  /// The extrinsics block, or filter::kNoBlock when T_RS is fixed.
  filter::BlockId block() const { return block_; }
  static filter::BlockLayout extrinsics_layout();

  /// Asks for the time offset's residual δt_d to be estimated (header comment), with prior N(0, prior_var_s2) (s²)
  /// and the robot predicted at most ±max_shift_s from the data's stamps. Before the robot joins a map.
  void estimate_time_offset(double prior_var_s2, double max_shift_s);
  /// The time offset block (1 row, s), or filter::kNoBlock.
  filter::BlockId time_block() const { return time_block_; }
  /// δt_d in `mean` (s); 0 when not estimated.
  double time_offset(const Eigen::VectorXd& mean) const;
  /// What the robot is predicted to for a datum of this sensor stamped t: t + time_shift(mean) (δt_d clamped to
  /// ±max_time_shift, in ns; 0 when not estimated).
  TimeNs time_shift(const Eigen::VectorXd& mean) const;
  TimeNs max_time_shift() const { return max_shift_; }
  /// The shift the robot was predicted with for the datum being processed (set by the System).
  void set_applied_time_shift(TimeNs shift) { applied_shift_ = shift; }
  TimeNs applied_time_shift() const { return applied_shift_; }

  /// Measurement size (2 for a camera).
  virtual int measurement_size() const = 0;
  /// Whether the sensor observes the map's landmarks (a camera). Sensors that do not (absolute position or pose
  /// sensors, slam/absolute_sensor.hpp) get no observations, no map management after their data and no tracking
  /// verdict of the health monitor.
  virtual bool observes_landmarks() const { return true; }
  /// h_S (any scale, direction matters) → measurement z; false if not projectable (behind, outside domain).
  virtual bool project(const Eigen::Vector3d& h_S, Eigen::Vector2d& z, Eigen::Matrix<double, 2, 3>* J_z_h) const = 0;
  /// Inside the sensor's field (e.g. image bounds less a margin).
  virtual bool in_field(const Eigen::Vector2d& z, double margin) const = 0;
  /// Back-projection: a ray in S (z = 1) and its Jacobian wrt the measurement.
  virtual bool back_project(const Eigen::Vector2d& z, Eigen::Vector3d& ray_S,
                            Eigen::Matrix<double, 3, 2>* J_ray_z) const = 0;

  DataManager* data_manager() const { return data_manager_.get(); }
  void set_data_manager(std::unique_ptr<DataManager> dm);

  /// Called when the sensor joins its robot and again when the robot joins a map (the extrinsics block, if
  /// requested, is created then).
  void attach(Robot& robot, int id);

 protected:
  Sensor(std::string name, math::Pose T_RS);

 private:
  int id_ = -1;
  std::string name_;
  Robot* robot_ = nullptr;
  math::Pose T_RS_;
  std::optional<Eigen::Matrix<double, 6, 6>> extrinsics_prior_;
  filter::BlockId block_ = filter::kNoBlock;
  std::optional<double> time_offset_prior_var_;
  filter::BlockId time_block_ = filter::kNoBlock;
  TimeNs max_shift_ = 0;
  TimeNs applied_shift_ = 0;
  std::unique_ptr<DataManager> data_manager_;
};

/// A pinhole camera with distortion (models::PinholeCamera).
class PinholeSensor final : public Sensor {
 public:
  PinholeSensor(std::string name, const models::CameraIntrinsics& intrinsics, math::Pose T_RS);
  int measurement_size() const override { return 2; }
  bool project(const Eigen::Vector3d& h_S, Eigen::Vector2d& z, Eigen::Matrix<double, 2, 3>* J_z_h) const override;
  bool in_field(const Eigen::Vector2d& z, double margin) const override;
  bool back_project(const Eigen::Vector2d& z, Eigen::Vector3d& ray_S,
                    Eigen::Matrix<double, 3, 2>* J_ray_z) const override;
  const models::PinholeCamera& camera() const { return camera_; }

 private:
  models::PinholeCamera camera_;
};

}  // namespace rtslam::slam
