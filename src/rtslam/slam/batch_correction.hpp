#pragma once
// One batched EKF correction from several observations of one sensor (the paper's "corrected in one batched update"
// of a RANSAC support set or an active-search round), shared by every point data manager: each observation is
// predicted at the map's mean, their compressed Jacobians are stacked over [shared blocks (robot, sensor
// extrinsics), landmark_1, ..., landmark_K] with measurements obs->z and noise sigma² I (+ the second-order
// inverse-depth term), and the state is corrected once. Options:
//  - iterations > 1: the iterated EKF (Bell & Cathey 1993; ROVIO's iterated update): h is relinearized at the
//    iterate x_i = x ⊕ dx_i and dx_{i+1} = K_i (z − h(x_i) + H_i dx_i), with K_i from the prior covariance and H_i,
//    until dx changes by less than iteration_tolerance; the correction applied is the last one (mean x ⊕ dx,
//    covariance (I − K H) P at the last linearization point). At a fixed point this is the Gauss-Newton step of the
//    MAP problem ½|x ⊖ x₀|²_P + ½|z − h(x)|²_R. iterations = 1 is the EKF.
//  - lin_mean: first-estimate Jacobians (observation.hpp): H at that mean, h at the current one (no iteration then).
// Workspaces are sized at construction: a correction allocates nothing.
#include <span>
#include <vector>

#include <Eigen/Core>

#include "rtslam/filter/state.hpp"
#include "rtslam/slam/observation.hpp"

namespace rtslam::slam {

struct BatchCorrectionOptions {
  double sigma_px = 1.0;
  bool second_order_depth = false;
  int iterations = 1;
  double iteration_tolerance = 1e-6;  // m, rad
  const Eigen::VectorXd* lin_mean = nullptr;
  // The caller's promise that every observation's Jacobians (H, R_depth) were computed at the state's current mean
  // (and lin_mean) and nothing changed the state since: only h is predicted again (the active search predicts its
  // candidates once a frame, then corrects them; a RANSAC hypothesis leaves its own h in them).
  bool jacobians_current = false;
};

class BatchCorrector {
 public:
  /// Workspaces for batches of up to max_observations observations.
  explicit BatchCorrector(int max_observations);
  /// Corrects `state` with the batch (measurements in obs->z; the observations are re-predicted, so their h/H
  /// describe the linearization used). Observations not projectable at the mean are left out; Status::Ok with
  /// used() == 0 when none is left (nothing changed).
  filter::CorrectionResult correct(filter::State& state, std::span<Observation* const> batch,
                                   const BatchCorrectionOptions& options);
  /// Observations used by the last correction.
  int used() const { return used_; }
  int max_observations() const { return max_obs_; }

 private:
  void assemble(const filter::State& state, std::span<Observation* const> batch, const BatchCorrectionOptions& o);
  int max_obs_;
  int used_ = 0, rows_ = 0, cols_ = 0, shared_cols_ = 0;
  std::vector<filter::BlockId> blocks_;
  std::vector<char> used_flags_;  // [k]: batch[k] is in the correction
  Eigen::MatrixXd H_, R_;
  Eigen::VectorXd y_, dx_, iter_dx_, iter_dx_prev_, iter_mean_;
};

}  // namespace rtslam::slam
