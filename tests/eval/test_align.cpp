// Alignment: Umeyama SE(3)/Sim(3), position+yaw and first-pose alignment recover known transforms exactly.
#include <gtest/gtest.h>

#include "eval/eval_test_utils.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/eval/align.hpp"

using namespace rtslam;
using namespace rtslam::eval;

namespace {

std::vector<Eigen::Vector3d> random_points(Rng& rng, int n) {
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < n; ++i) pts.push_back(randn_vec<3>(rng, 2.0));
  return pts;
}

std::vector<Eigen::Vector3d> transform(const Sim3& S, const std::vector<Eigen::Vector3d>& pts) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : pts) out.push_back(S.apply(p));
  return out;
}

}  // namespace

TEST(Umeyama, RecoversRandomSim3ExactlyFromNoiselessPoints) {
  Rng rng(42);
  for (int trial = 0; trial < 50; ++trial) {
    const Sim3 S = test::random_sim3(rng, true);
    const auto src = random_points(rng, 3 + trial);
    const Sim3 fit = umeyama(src, transform(S, src), true);
    EXPECT_NEAR(fit.s, S.s, 1e-12 * S.s) << trial;
    EXPECT_LT((fit.R - S.R).norm(), 1e-12) << trial;
    EXPECT_LT((fit.t - S.t).norm(), 1e-11) << trial;
    EXPECT_NEAR(fit.R.determinant(), 1.0, 1e-12);
  }
}

TEST(Umeyama, RecoversRandomSe3ExactlyAndKeepsUnitScale) {
  Rng rng(7);
  for (int trial = 0; trial < 50; ++trial) {
    const Sim3 S = test::random_sim3(rng, false);
    const auto src = random_points(rng, 10);
    const Sim3 fit = umeyama(src, transform(S, src), false);
    EXPECT_EQ(fit.s, 1.0);
    EXPECT_LT((fit.R - S.R).norm(), 1e-12) << trial;
    EXPECT_LT((fit.t - S.t).norm(), 1e-11) << trial;
  }
}

TEST(Umeyama, PlanarPointsGiveAProperRotationNotAReflection) {
  // Coplanar points (rank 2): the det correction must pick the rotation.
  Rng rng(3);
  std::vector<Eigen::Vector3d> src;
  for (int i = 0; i < 20; ++i) src.emplace_back(randn(rng), randn(rng), 0.0);
  const Sim3 S = test::random_sim3(rng, true);
  const Sim3 fit = umeyama(src, transform(S, src), true);
  EXPECT_NEAR(fit.R.determinant(), 1.0, 1e-12);
  EXPECT_LT((fit.R - S.R).norm(), 1e-10);
  EXPECT_NEAR(fit.s, S.s, 1e-10);
}

TEST(Umeyama, MinimizesSquaredErrorWithNoise) {
  // With noise the fit is the least-squares optimum: any perturbation of it increases the cost.
  Rng rng(11);
  const Sim3 S = test::random_sim3(rng, true);
  const auto src = random_points(rng, 40);
  auto dst = transform(S, src);
  for (auto& p : dst) p += randn_vec<3>(rng, 0.05);
  const Sim3 fit = umeyama(src, dst, true);
  auto cost = [&](const Sim3& T) {
    double c = 0;
    for (std::size_t i = 0; i < src.size(); ++i) c += (dst[i] - T.apply(src[i])).squaredNorm();
    return c;
  };
  const double c0 = cost(fit);
  for (int k = 0; k < 20; ++k) {
    Sim3 P = fit;
    P.R = test::exp_q(randn_vec<3>(rng, 1e-3)).toRotationMatrix() * P.R;
    P.t += randn_vec<3>(rng, 1e-3);
    P.s *= 1.0 + 1e-3 * randn(rng);
    EXPECT_GT(cost(P), c0);
  }
}

TEST(Umeyama, DegenerateOrMismatchedInputsThrow) {
  std::vector<Eigen::Vector3d> line;
  for (int i = 0; i < 5; ++i) line.emplace_back(i, 0, 0);
  EXPECT_THROW(umeyama(line, line, false), DataError);
  EXPECT_THROW(umeyama({{0, 0, 0}, {1, 0, 0}}, {{0, 0, 0}, {1, 0, 0}}, false), DataError);
  EXPECT_THROW(umeyama(line, {{0, 0, 0}}, false), DataError);
}

TEST(PositionYaw, RecoversYawAndTranslationExactly) {
  Rng rng(5);
  for (int trial = 0; trial < 20; ++trial) {
    Sim3 S;
    S.R = rot_z(randu(rng, -3.1, 3.1));
    S.t = randn_vec<3>(rng, 2.0);
    const auto src = random_points(rng, 15);
    const Sim3 fit = align_position_yaw(src, transform(S, src));
    EXPECT_LT((fit.R - S.R).norm(), 1e-12) << trial;
    EXPECT_LT((fit.t - S.t).norm(), 1e-12) << trial;
    EXPECT_NEAR(fit.R(2, 2), 1.0, 1e-15);  // a rotation about z only
  }
}

TEST(PositionYaw, DoesNotTiltWhenTheTrueTransformHasRollPitch) {
  Rng rng(6);
  Sim3 S;
  S.R = test::exp_q(Eigen::Vector3d(0.2, -0.1, 0.7)).toRotationMatrix();
  const auto src = random_points(rng, 15);
  const Sim3 fit = align_position_yaw(src, transform(S, src));
  EXPECT_NEAR(fit.R(2, 2), 1.0, 1e-15);
  EXPECT_NEAR(fit.R(0, 2), 0.0, 1e-15);
}

TEST(Alignment, FirstPoseAlignmentMapsFirstEstimateOntoFirstTruth) {
  Rng rng(9);
  const Trajectory gt = test::wavy_trajectory(30);
  const Sim3 S = test::random_sim3(rng, false);
  const Trajectory est = apply_alignment(S, gt);  // the truth seen in another world frame
  const Sim3 fit = compute_alignment(est, gt, Alignment::Origin);
  const Trajectory back = apply_alignment(fit, est);
  for (std::size_t i = 0; i < gt.poses.size(); ++i) {
    EXPECT_LT((back.poses[i].p_WR - gt.poses[i].p_WR).norm(), 1e-12);
    EXPECT_LT(back.poses[i].q_WR.angularDistance(gt.poses[i].q_WR), 1e-9);
  }
}

TEST(Alignment, ApplyCarriesCovarianceIntoTheNewWorldFrame) {
  Trajectory t = test::wavy_trajectory(2);
  Eigen::Matrix<double, 6, 6> P = Eigen::Matrix<double, 6, 6>::Identity();
  P(0, 0) = 4.0;  // large along world x
  t.poses[0].cov = P;
  Sim3 S;
  S.R = rot_z(M_PI / 2);  // world x becomes world y
  S.s = 2.0;
  const Trajectory out = apply_alignment(S, t);
  EXPECT_NEAR((*out.poses[0].cov)(1, 1), 16.0, 1e-12);
  EXPECT_NEAR((*out.poses[0].cov)(0, 0), 4.0, 1e-12);
  EXPECT_NEAR((*out.poses[0].cov)(3, 3), 1.0, 1e-12);  // δθ in the robot frame: unchanged
}

TEST(Alignment, ParsesNamesAndRejectsUnknownOnes) {
  EXPECT_EQ(parse_alignment("posyaw"), Alignment::PosYaw);
  EXPECT_EQ(to_string(parse_alignment("sim3")), "sim3");
  EXPECT_THROW(parse_alignment("se2"), ConfigError);
}

namespace rtslam::eval {
namespace {

// Issue 17: a 3-pose `eval --align sim3` gave a scale of 0.009 and an ATE of 4 um.
TEST(AlignmentGeometry, TooFewPosesForTheFitAreRefused) {
  const std::vector<Eigen::Vector3d> three = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  const std::vector<Eigen::Vector3d> est = {{0, 0, 0}, {0.5, 3, 0}, {1, 0, 2}};
  EXPECT_THROW(check_alignment_geometry(est, three, Alignment::Sim3), DataError);
  EXPECT_THROW(check_alignment_geometry(est, three, Alignment::Se3), DataError);
  EXPECT_NO_THROW(check_alignment_geometry(est, three, Alignment::Origin));
  Trajectory e, g;
  for (int i = 0; i < 3; ++i) {
    StampedPose p;
    p.t = i;
    p.p_WR = est[static_cast<std::size_t>(i)];
    e.poses.push_back(p);
    p.p_WR = three[static_cast<std::size_t>(i)];
    g.poses.push_back(p);
  }
  EXPECT_THROW(compute_alignment(e, g, Alignment::Sim3), DataError);
}

TEST(AlignmentGeometry, CollinearPositionsAreRefusedAndASpreadTrajectoryPasses) {
  std::vector<Eigen::Vector3d> line, noisy_line, spread;
  for (int i = 0; i < 10; ++i) {
    line.emplace_back(i, 0, 0);
    noisy_line.emplace_back(i, 1e-5 * (i % 2), 0);  // 5 um across 2.9 m: still a line
    spread.emplace_back(i, std::sin(i), 0.1 * i * i);
  }
  EXPECT_THROW(check_alignment_geometry(spread, line, Alignment::Sim3), DataError);
  EXPECT_THROW(check_alignment_geometry(noisy_line, spread, Alignment::Se3), DataError);
  EXPECT_NO_THROW(check_alignment_geometry(spread, spread, Alignment::Sim3));
  EXPECT_NO_THROW(check_alignment_geometry(line, line, Alignment::PosYaw));
}

}  // namespace
}  // namespace rtslam::eval
