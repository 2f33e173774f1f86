#pragma once
// Landmarks: a state block plus a descriptor, and one Observation per sensor of the map (created with the
// landmark, same lifetime). Parametrizations: AHP [p0 m ρ] (7) and Euclidean [x y z] (3); an AHP landmark is
// replaced by a Euclidean one when it has converged (reparametrization keeps id, observations and descriptor).
#include <any>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "rtslam/filter/state.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/fwd.hpp"
#include "rtslam/slam/observation.hpp"

namespace rtslam::slam {

enum class LandmarkType { AhpPoint, EuclideanPoint };

/// Jacobian of h_S wrt a landmark block (3 × tangent size, at most kMaxLandmarkTangent): no heap allocation.
constexpr int kMaxLandmarkTangent = 16;
using LandmarkJacobian = Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::ColMajor, 3, kMaxLandmarkTangent>;
const char* to_string(LandmarkType t);

class Landmark {
 public:
  virtual ~Landmark();
  Landmark(const Landmark&) = delete;
  Landmark& operator=(const Landmark&) = delete;

  int id() const { return id_; }
  LandmarkType type() const { return type_; }
  filter::BlockId block() const { return block_; }
  virtual filter::BlockLayout layout() const = 0;

  /// h_S, the landmark's homogeneous direction in sensor frame S, from a mean vector; Jacobians wrt the sensor
  /// pose [δp_WS δθ_WS] (3x6) and wrt the landmark block (3 × tangent size).
  virtual Eigen::Vector3d to_sensor(const Eigen::VectorXd& mean, const math::Pose& T_WS,
                                    Eigen::Matrix<double, 3, 6>* J_h_TWS, LandmarkJacobian* J_h_L) const = 0;
  /// Euclidean position in W (for maps, evaluation, display).
  virtual Eigen::Vector3d position(const Eigen::VectorXd& mean) const = 0;
  /// Parametrizations with an inverse-distance coordinate ρ: ∂h_S/∂ρ seen from T_WS (h_S is linear in ρ, the
  /// projection is not) and the current variance of ρ, for the second-order term of the measurement noise
  /// (observation.hpp). False for the others.
  virtual bool inverse_depth_direction(const filter::State& state, const Eigen::VectorXd& mean, const math::Pose& T_WS,
                                       Eigen::Vector3d& dh_drho, double& var_rho) const {
    (void)state, (void)mean, (void)T_WS, (void)dh_drho, (void)var_rho;
    return false;
  }
  /// A change of the map's unit of length (Map::scale_lengths), as Robot::scale_lengths: `mean` is the block's;
  /// the first estimate changes with it.
  virtual bool can_scale_lengths() const { return false; }
  virtual void scale_lengths(double c, const Eigen::Vector3d& centre, Eigen::Ref<Eigen::VectorXd> mean,
                             Eigen::Ref<Eigen::VectorXd> d);

  std::vector<Observation>& observations() { return observations_; }
  const std::vector<Observation>& observations() const { return observations_; }
  Observation* observation_of(const Sensor& s);

  /// Free-form descriptor for the data manager (e.g. the initial patch and view); a known-association
  /// simulation stores the true point id here.
  std::any descriptor;
  /// The block's mean when this parametrization was created (first-estimate Jacobians: the linearization point of
  /// Euclidean landmarks, which are created by reparametrization once their depth has converged).
  Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 16, 1> first_estimate;
  /// The map frame (FrameStats::frame) it was made in, for the map manager, and the sensor whose datum made it.
  long frame_created = 0;
  int sensor_created = -1;

 protected:
  Landmark(LandmarkType type, int id, filter::BlockId block) : id_(id), type_(type), block_(block) {}
  int ambient_offset_ = 0;  // of the block in the mean vector, cached by Map

 private:
  friend class Map;
  int id_;
  LandmarkType type_;
  filter::BlockId block_;
  std::vector<Observation> observations_;
};

class AhpPointLandmark final : public Landmark {
 public:
  AhpPointLandmark(int id, filter::BlockId block) : Landmark(LandmarkType::AhpPoint, id, block) {}
  filter::BlockLayout layout() const override { return filter::BlockLayout::euclidean(7); }
  Eigen::Vector3d to_sensor(const Eigen::VectorXd& mean, const math::Pose& T_WS, Eigen::Matrix<double, 3, 6>* J_h_TWS,
                            LandmarkJacobian* J_h_L) const override;
  Eigen::Vector3d position(const Eigen::VectorXd& mean) const override;
  /// ∂h_S/∂ρ = −R_WSᵀ (p_WS − p0), and var(ρ).
  bool inverse_depth_direction(const filter::State& state, const Eigen::VectorXd& mean, const math::Pose& T_WS,
                               Eigen::Vector3d& dh_drho, double& var_rho) const override;
  /// p0 about the centre, m unchanged, ρ / c (the point p0 + m/ρ about the centre).
  bool can_scale_lengths() const override { return true; }
  void scale_lengths(double c, const Eigen::Vector3d& centre, Eigen::Ref<Eigen::VectorXd> mean,
                     Eigen::Ref<Eigen::VectorXd> d) override;
};

class EuclideanPointLandmark final : public Landmark {
 public:
  EuclideanPointLandmark(int id, filter::BlockId block) : Landmark(LandmarkType::EuclideanPoint, id, block) {}
  filter::BlockLayout layout() const override { return filter::BlockLayout::euclidean(3); }
  Eigen::Vector3d to_sensor(const Eigen::VectorXd& mean, const math::Pose& T_WS, Eigen::Matrix<double, 3, 6>* J_h_TWS,
                            LandmarkJacobian* J_h_L) const override;
  Eigen::Vector3d position(const Eigen::VectorXd& mean) const override;
  bool can_scale_lengths() const override { return true; }
  void scale_lengths(double c, const Eigen::Vector3d& centre, Eigen::Ref<Eigen::VectorXd> mean,
                     Eigen::Ref<Eigen::VectorXd> d) override;
};

}  // namespace rtslam::slam
