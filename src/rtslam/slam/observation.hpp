#pragma once
// One Observation per sensor–landmark pair, with the landmark's lifetime. It keeps what the data manager
// computed last (prediction, compressed Jacobian, innovation covariance, innovation), the appearance slots
// (filled by image data managers), event counters for the map manager, and the linearization point the
// Jacobians were evaluated at (so first-estimate Jacobians can be added without redesign).
#include <any>
#include <array>

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
  std::array<filter::BlockId, 2> blocks{filter::kNoBlock, filter::kNoBlock};  // [robot, landmark]
  // Compressed Jacobian: robot tangent cols then landmark tangent cols (fixed maximum: no heap allocation).
  Eigen::Matrix<double, 2, Eigen::Dynamic, Eigen::ColMajor, 2, 64> H;
  Eigen::Matrix2d R = Eigen::Matrix2d::Identity();
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
/// the compressed H over [robot block, landmark block]. Sets projectable/visible (with `margin` px). Returns
/// `visible`. Allocation-free after the first call for a given observation.
bool predict_observation(const filter::State& state, const Eigen::VectorXd& mean, Observation& obs, double margin,
                         bool with_jacobians);

/// S = H P Hᵀ + R for a predicted observation (R = sigma² I).
void compute_innovation_covariance(const filter::State& state, Observation& obs, double sigma);

}  // namespace rtslam::slam
