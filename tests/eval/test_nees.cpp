// NEES: a correctly sampled Gaussian pose error averages its dimension (6), first-pose alignment removes a change
// of world frame, and over-confident covariances leave the chi-square band.
#include <cmath>

#include <gtest/gtest.h>

#include "eval/eval_test_utils.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/eval/align.hpp"
#include "rtslam/eval/chi2.hpp"
#include "rtslam/eval/nees.hpp"

using namespace rtslam;
using namespace rtslam::eval;

namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;

Mat6 random_spd(Rng& rng) {
  Mat6 A;
  for (int i = 0; i < 36; ++i) A(i / 6, i % 6) = randn(rng);
  Mat6 P = 0.01 * A * A.transpose() + 1e-4 * Mat6::Identity();
  // Positions in cm..dm, angles in mrad..crad.
  Eigen::Matrix<double, 6, 1> scale;
  scale << 0.5, 0.5, 0.5, 0.1, 0.1, 0.1;
  return scale.asDiagonal() * P * scale.asDiagonal();
}

// An estimate of `gt` whose error e = true ⊖ estimate is drawn from N(0, P_i), P_i stored with the pose; the first
// pose is exact (the gauge) with zero covariance. `cov_scale` scales the stored covariance (not the draw).
Trajectory sample_estimate(const Trajectory& gt, Rng& rng, double cov_scale = 1.0,
                           std::vector<Vector6d>* errors = nullptr) {
  Trajectory est = gt;
  for (std::size_t i = 0; i < est.poses.size(); ++i) {
    auto& p = est.poses[i];
    if (i == 0) {
      p.cov = Mat6::Zero();
      continue;
    }
    const Mat6 P = random_spd(rng);
    const Mat6 L = P.llt().matrixL();
    const Vector6d e = L * randn_vec<6>(rng);
    p.p_WR = gt.poses[i].p_WR - e.head<3>();
    p.q_WR = gt.poses[i].q_WR * test::exp_q(e.tail<3>()).conjugate();
    p.cov = cov_scale * P;
    if (errors) errors->push_back(e);
  }
  return est;
}

}  // namespace

TEST(Nees, EqualsTheMahalanobisNormOfTheSampledError) {
  Rng rng(17);
  const Trajectory gt = test::wavy_trajectory(50);
  std::vector<Vector6d> errors;
  const Trajectory est = sample_estimate(gt, rng, 1.0, &errors);
  const NeesSeries s = compute_nees(est, gt);
  ASSERT_EQ(s.nees.size(), 49u);
  EXPECT_EQ(s.skipped, 1u);  // the gauge pose with zero covariance
  for (std::size_t k = 0; k < s.nees.size(); ++k) {
    EXPECT_LT((s.error[k] - errors[k]).norm(), 1e-9) << k;
    const Mat6& P = *est.poses[k + 1].cov;
    EXPECT_NEAR(s.nees[k], errors[k].dot(P.ldlt().solve(errors[k])), 1e-8 * s.nees[k]) << k;
  }
}

TEST(Nees, CorrectlySampledGaussianErrorAveragesItsDimension) {
  Rng rng(2024);
  const Trajectory gt = test::wavy_trajectory(3001);
  const NeesSeries s = compute_nees(sample_estimate(gt, rng), gt);
  const NeesSummary sum = summarize_nees(s);
  // Mean of 3000 χ²(6) draws: 6 ± sqrt(12/3000) = 6 ± 0.063; 5σ tolerance.
  EXPECT_NEAR(sum.mean, 6.0, 0.32);
  EXPECT_NEAR(sum.fraction_in_band, 0.99, 0.01);
}

TEST(Nees, FirstPoseAlignmentRemovesAChangeOfWorldFrame) {
  Rng rng(8);
  const Trajectory gt = test::wavy_trajectory(200);
  const Trajectory est = sample_estimate(gt, rng);
  const NeesSeries ref = compute_nees(est, gt);
  // The filter's world differs from the truth's by a rigid transform; the covariance moves with it.
  const Trajectory est_other_world = apply_alignment(test::random_sim3(rng, false), est);
  const NeesSeries moved = compute_nees(est_other_world, gt);
  ASSERT_EQ(moved.nees.size(), ref.nees.size());
  for (std::size_t k = 0; k < ref.nees.size(); ++k) EXPECT_NEAR(moved.nees[k], ref.nees[k], 1e-7 * ref.nees[k] + 1e-9);
}

TEST(Nees, AverageOverRunsStaysInsideTheBandWhenConsistentAndLeavesItWhenOverconfident) {
  Rng rng(31);
  const Trajectory gt = test::wavy_trajectory(101);
  std::vector<NeesSeries> consistent, overconfident;
  for (int run = 0; run < 20; ++run) {
    consistent.push_back(compute_nees(sample_estimate(gt, rng), gt));
    overconfident.push_back(compute_nees(sample_estimate(gt, rng, 0.25), gt));
  }
  const AverageNees a = average_nees(consistent);
  ASSERT_EQ(a.t.size(), 100u);
  EXPECT_EQ(a.n_runs.front(), 20);
  const auto [lo, hi] = nees_band(6, 20);
  EXPECT_DOUBLE_EQ(a.lo.front(), lo);
  EXPECT_DOUBLE_EQ(a.hi.front(), hi);
  const NeesSummary s = summarize_average_nees(a);
  EXPECT_NEAR(s.mean, 6.0, 0.3);
  EXPECT_GE(s.fraction_in_band, 0.95);
  EXPECT_EQ(s.n_runs, 20);
  const NeesSummary bad = summarize_average_nees(average_nees(overconfident));
  EXPECT_NEAR(bad.mean, 24.0, 1.5);  // covariance 4× too small → NEES 4× too large
  EXPECT_LE(bad.fraction_in_band, 0.05);
}

TEST(Nees, NoUsableCovarianceThrows) {
  const Trajectory gt = test::wavy_trajectory(5);
  EXPECT_THROW(compute_nees(gt, gt), DataError);
  Trajectory shorter = gt;
  shorter.poses.pop_back();
  EXPECT_THROW(compute_nees(shorter, gt), DataError);
}
