#pragma once
// Sensors hang off their robot by T_RS: fixed (the calibration), or estimated as a block of the map, [p_RS q_RS]
// with tangent [δp δθ] (the paper's "sensors belong to the map": camera–IMU extrinsics refined online). A point
// sensor projects a landmark's homogeneous direction h_S (in S) to a measurement.
#include <memory>
#include <optional>
#include <string>

#include <Eigen/Core>

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
  /// T_WS = T_WR T_RS for the robot pose (and the extrinsics, when estimated) in `mean`; J_TWS_TWR and J_TWS_TRS
  /// (6x6, [δp δθ]) if requested (J_TWS_TRS only for an estimated T_RS).
  math::Pose pose_in_world(const Eigen::VectorXd& mean, Eigen::Matrix<double, 6, 6>* J_TWS_TWR = nullptr,
                           Eigen::Matrix<double, 6, 6>* J_TWS_TRS = nullptr) const;

  /// Asks for T_RS to be estimated, starting from the calibration with this [δp δθ] prior covariance. Must be
  /// called before the robot joins a map (the block is created then).
  void estimate_extrinsics(const Eigen::Matrix<double, 6, 6>& prior_cov);
  /// The extrinsics block, or filter::kNoBlock when T_RS is fixed.
  filter::BlockId block() const { return block_; }
  static filter::BlockLayout extrinsics_layout();

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
