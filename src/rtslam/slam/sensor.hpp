#pragma once
// Sensors hang off their robot by T_RS (fixed here; estimating it as a map block is a later extension).
// A point sensor projects a landmark's homogeneous direction h_S (in S) to a measurement.
#include <memory>
#include <string>

#include <Eigen/Core>

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
  const math::Pose& T_RS() const { return T_RS_; }
  /// T_WS = T_WR T_RS for the robot pose in `mean`; J_TWS_TWR (6x6, [δp δθ]) if requested.
  math::Pose pose_in_world(const Eigen::VectorXd& mean, Eigen::Matrix<double, 6, 6>* J_TWS_TWR = nullptr) const;

  /// Measurement size (2 for a camera).
  virtual int measurement_size() const = 0;
  /// h_S (any scale, direction matters) → measurement z; false if not projectable (behind, outside domain).
  virtual bool project(const Eigen::Vector3d& h_S, Eigen::Vector2d& z, Eigen::Matrix<double, 2, 3>* J_z_h) const = 0;
  /// Inside the sensor's field (e.g. image bounds less a margin).
  virtual bool in_field(const Eigen::Vector2d& z, double margin) const = 0;
  /// Back-projection: a ray in S (z = 1) and its Jacobian wrt the measurement.
  virtual bool back_project(const Eigen::Vector2d& z, Eigen::Vector3d& ray_S,
                            Eigen::Matrix<double, 3, 2>* J_ray_z) const = 0;

  DataManager* data_manager() const { return data_manager_.get(); }
  void set_data_manager(std::unique_ptr<DataManager> dm);

  void attach(Robot& robot, int id);

 protected:
  Sensor(std::string name, math::Pose T_RS);

 private:
  int id_ = -1;
  std::string name_;
  Robot* robot_ = nullptr;
  math::Pose T_RS_;
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
