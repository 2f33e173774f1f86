#pragma once
// Pose NEES (MATH.md "Consistency"). The ground truth is first brought into the filter's world frame by the
// first-pose alignment (the filter's gauge): gt' = S ∘ gt with S = T_est0 · T_gt0⁻¹, which leaves the estimate and
// its covariance untouched. Then, per pose,
//   e = [p_gt' − p_est ; Log(q_est⁻¹ ⊗ q_gt')]     (true ⊖ estimate, right perturbation, δθ in the robot frame)
//   ε = eᵀ P⁻¹ e                                     (P: the 6×6 [δp δθ] covariance written with the pose)
// Poses whose covariance is not positive definite (e.g. the gauge pose with zero covariance) are skipped.
// Over N independent runs the average ε̄(t) satisfies N ε̄ ~ χ²(6N): see nees_band() in chi2.hpp.
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "rtslam/core/trajectory.hpp"

namespace rtslam::eval {

using Vector6d = Eigen::Matrix<double, 6, 1>;

struct NeesSeries {
  std::vector<TimeNs> t;
  std::vector<double> nees;
  std::vector<Vector6d> error;  // e = true ⊖ estimate [δp (m, world); δθ (rad, robot frame)]
  std::vector<Vector6d> sigma;  // sqrt of the covariance diagonal, same order
  std::size_t skipped = 0;      // poses without a usable covariance
};

/// NEES of an associated estimate (with covariances) against its ground truth. Throws DataError when the lengths
/// differ, the trajectories are empty, or no pose carries a positive-definite covariance.
NeesSeries compute_nees(const Trajectory& est, const Trajectory& gt);

/// Mean of the NEES over time, and the fraction of poses inside the two-sided band for one run.
struct NeesSummary {
  double mean = 0.0;
  double fraction_in_band = 0.0;
  double band_lo = 0.0, band_hi = 0.0;
  int n_runs = 1;
  std::size_t n = 0;
};
NeesSummary summarize_nees(const NeesSeries& s, double confidence = 0.99);

/// NEES averaged over runs at each timestamp (runs of one sequence share their frame timestamps; a timestamp
/// counts the runs that have a NEES there), with the band for that number of runs.
struct AverageNees {
  std::vector<TimeNs> t;
  std::vector<double> mean;
  std::vector<int> n_runs;
  std::vector<double> lo, hi;
};
AverageNees average_nees(const std::vector<NeesSeries>& runs, double confidence = 0.99);

/// Summary of an averaged NEES: its mean over time and the fraction of timestamps inside their band.
NeesSummary summarize_average_nees(const AverageNees& avg);

nlohmann::json to_json(const NeesSummary& s);

}  // namespace rtslam::eval
