#pragma once
// One Observation per sensor–landmark pair, with the landmark's lifetime. It keeps what the data manager
// computed last (prediction, compressed Jacobian, innovation covariance, innovation), the appearance slots
// (filled by image data managers), event counters for the map manager, and the linearization point the
// Jacobians were evaluated at (so first-estimate Jacobians can be added without redesign).
#include <any>
#include <array>
#include <span>

#include <Eigen/Core>

#include "rtslam/filter/state.hpp"
#include "rtslam/slam/fwd.hpp"

namespace rtslam::slam {

struct ObservationCounters {
  long searched = 0;      // times searched (active search / RANSAC)
  long matched = 0;       // times a measurement was found
  long updated = 0;       // times used in a correction
  long failed = 0;        // searched but not matched, or gated out
  long last_visible_frame = -1;
  long last_updated_frame = -1;
};

struct Observation {
  Sensor* sensor = nullptr;
  Landmark* landmark = nullptr;

  // Prediction (h, Jacobians over the involved blocks, S = H P Hᵀ + R).
  bool projectable = false;  // in front of the sensor and inside its model's domain
  bool visible = false;      // projectable and inside the field (image)
  Eigen::Vector2d h = Eigen::Vector2d::Zero();
  // Involved blocks: [robot, sensor extrinsics (when estimated), sensor time offset (when estimated), landmark]; the
  // landmark comes last, and the blocks before it are shared by every observation of the sensor (batched corrections
  // put them first).
  std::array<filter::BlockId, 4> blocks{filter::kNoBlock, filter::kNoBlock, filter::kNoBlock, filter::kNoBlock};
  int block_count = 0;
  std::span<const filter::BlockId> involved() const { return {blocks.data(), static_cast<std::size_t>(block_count)}; }
  std::span<const filter::BlockId> sensor_blocks() const {
    return {blocks.data(), static_cast<std::size_t>(block_count - 1)};
  }
  filter::BlockId landmark_block() const { return blocks[static_cast<std::size_t>(block_count - 1)]; }
  // Compressed Jacobian: the columns of the involved blocks in that order (fixed maximum: no heap allocation).
  Eigen::Matrix<double, 2, Eigen::Dynamic, Eigen::ColMajor, 2, 64> H;
  Eigen::Matrix2d R = Eigen::Matrix2d::Identity();
  // Second-order term of the measurement for inverse-depth landmarks (computed with the Jacobians): the
  // projection is curved along ρ, d²z/dρ² = −2 (∂h_z/∂ρ / h_z) dz/dρ (distortion's curvature neglected), and a
  // Gaussian second-order filter adds ½ (d²z/dρ²)(d²z/dρ²)ᵀ σ_ρ⁴ to R. It is large while a young landmark's depth is
  // uncertain and the camera has moved from its anchor, and vanishes as the depth converges.
  Eigen::Matrix2d R_depth = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d S = Eigen::Matrix2d::Identity();
  double depth = 0.0;  // h_S.z / |h_S| direction cosine × distance when known (AHP: along-ray distance)

  // Measurement and innovation.
  Eigen::Vector2d z = Eigen::Vector2d::Zero();
  Eigen::Vector2d y = Eigen::Vector2d::Zero();
  double mahalanobis2 = 0.0;

  // Linearization point the Jacobians used: T_WS and the landmark mean.
  Eigen::Matrix<double, 7, 1> lin_T_WS = Eigen::Matrix<double, 7, 1>::Zero();  // [p q(wxyz)]
  Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 16, 1> lin_landmark;

  // Appearance (image data managers): predicted and observed.
  std::any predicted_appearance;
  std::any observed_appearance;

  ObservationCounters counters;
};

/// Predicts an observation from a mean vector (the map's, or a RANSAC hypothesis): h, and if `with_jacobians`,
/// the compressed H over the involved blocks [robot, (extrinsics,) (time offset,) landmark]. Sets projectable/visible (with `margin` px). Returns
/// `visible`. Allocation-free after the first call for a given observation. With `lin_mean` (first-estimate
/// Jacobians), H is evaluated at that mean instead (h still at `mean`); the projection must be valid there too,
/// else H falls back to `mean`.
bool predict_observation(const filter::State& state, const Eigen::VectorXd& mean, Observation& obs, double margin,
                         bool with_jacobians, const Eigen::VectorXd* lin_mean = nullptr);

/// The measurement noise of a predicted observation: sigma² I, plus R_depth when `second_order` is set.
Eigen::Matrix2d measurement_noise(const Observation& obs, double sigma, bool second_order);

/// S = H P Hᵀ + R for a predicted observation, R = measurement_noise(obs, sigma, second_order).
void compute_innovation_covariance(const filter::State& state, Observation& obs, double sigma,
                                   bool second_order = false);

}  // namespace rtslam::slam
