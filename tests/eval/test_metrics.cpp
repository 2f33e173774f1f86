// ATE/RPE/association with evo's definitions: analytic cases, and agreement with an independent reference
// implementation (Horn's quaternion alignment, Eigen isometries) on noisy trajectories to 1e-9 relative.
#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "eval/eval_test_utils.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/eval/metrics.hpp"
#include "rtslam/eval/run_eval.hpp"

using namespace rtslam;
using namespace rtslam::eval;

namespace {

Trajectory noisy_copy(const Trajectory& gt, Rng& rng, double sigma_p, double sigma_q) {
  Trajectory est = gt;
  Eigen::Vector3d drift = Eigen::Vector3d::Zero();
  for (auto& p : est.poses) {
    drift += randn_vec<3>(rng, sigma_p);
    p.p_WR += drift + randn_vec<3>(rng, sigma_p);
    p.q_WR = p.q_WR * test::exp_q(randn_vec<3>(rng, sigma_q));
  }
  return est;
}

// Horn (1987) closed-form absolute orientation with unit quaternions, plus the least-squares scale
// s = Σ y'ᵀ R x' / Σ |x'|² (the asymmetric scale, which is Umeyama's).
Sim3 horn(const Trajectory& est, const Trajectory& gt, bool with_scale) {
  const std::size_t n = est.poses.size();
  Eigen::Vector3d cx = Eigen::Vector3d::Zero(), cy = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    cx += est.poses[i].p_WR;
    cy += gt.poses[i].p_WR;
  }
  cx /= n;
  cy /= n;
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < n; ++i) M += (est.poses[i].p_WR - cx) * (gt.poses[i].p_WR - cy).transpose();
  Eigen::Matrix4d N;
  N << M(0, 0) + M(1, 1) + M(2, 2), M(1, 2) - M(2, 1), M(2, 0) - M(0, 2), M(0, 1) - M(1, 0),
      M(1, 2) - M(2, 1), M(0, 0) - M(1, 1) - M(2, 2), M(0, 1) + M(1, 0), M(2, 0) + M(0, 2),
      M(2, 0) - M(0, 2), M(0, 1) + M(1, 0), -M(0, 0) + M(1, 1) - M(2, 2), M(1, 2) + M(2, 1),
      M(0, 1) - M(1, 0), M(2, 0) + M(0, 2), M(1, 2) + M(2, 1), -M(0, 0) - M(1, 1) + M(2, 2);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> es(N);
  const Eigen::Vector4d q = es.eigenvectors().col(3);
  Sim3 S;
  S.R = Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
  if (with_scale) {
    double num = 0, den = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d x = est.poses[i].p_WR - cx;
      num += (gt.poses[i].p_WR - cy).dot(S.R * x);
      den += x.squaredNorm();
    }
    S.s = num / den;
  }
  S.t = cy - S.s * S.R * cx;
  return S;
}

Eigen::Isometry3d iso(const StampedPose& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = p.q_WR.normalized().toRotationMatrix();
  T.translation() = p.p_WR;
  return T;
}

double angle_deg(const Eigen::Matrix3d& R) {
  return Eigen::AngleAxisd(R).angle() * 180.0 / M_PI;
}

StampedPose at(TimeNs t) {
  StampedPose p;
  p.t = t;
  return p;
}

void expect_rel(double a, double b, double rel, const char* what) {
  EXPECT_LE(std::abs(a - b), rel * std::max(std::abs(b), 1e-12)) << what << ": " << a << " vs " << b;
}

}  // namespace

TEST(ErrorStats, MatchesNumpyDefinitions) {
  const ErrorStats s = compute_stats({3.0, 1.0, 4.0, 2.0});
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.median, 2.5);            // mean of the two middle values
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(1.25));   // population std (numpy ddof = 0)
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(7.5));
  EXPECT_DOUBLE_EQ(s.sse, 30.0);
  EXPECT_DOUBLE_EQ(s.min, 1.0);
  EXPECT_DOUBLE_EQ(s.max, 4.0);
  EXPECT_DOUBLE_EQ(compute_stats({5.0, 1.0, 3.0}).median, 3.0);
  EXPECT_THROW(compute_stats({}), DataError);
}

TEST(Ate, ScaledPositionsGiveKnownErrorsWithoutAlignment) {
  Trajectory gt = test::wavy_trajectory(40);
  Trajectory est = gt;
  for (auto& p : est.poses) p.p_WR *= 2.0;
  EvalOptions o;
  o.align = Alignment::None;
  const EvalResult r = evaluate(est, gt, o);
  for (std::size_t i = 0; i < gt.poses.size(); ++i) EXPECT_NEAR(r.ate.trans_err_m[i], gt.poses[i].p_WR.norm(), 1e-12);
  EXPECT_NEAR(r.ate.rot_deg.max, 0.0, 1e-6);
  // RPE over 1 frame: E = Q_rel⁻¹ P_rel has translation R_relᵀ(2Δ − Δ), of norm |Δp|.
  ASSERT_TRUE(r.rpe);
  for (std::size_t k = 0; k < r.rpe->pairs.size(); ++k) {
    const auto [i, j] = r.rpe->pairs[k];
    EXPECT_NEAR(r.rpe->trans_err_m[k], (gt.poses[j].p_WR - gt.poses[i].p_WR).norm(), 1e-12);
  }
  // A Sim(3) alignment removes the scale completely and reports it.
  o.align = Alignment::Sim3;
  const EvalResult r2 = evaluate(est, gt, o);
  EXPECT_NEAR(r2.alignment.s, 0.5, 1e-12);
  EXPECT_NEAR(r2.sim3_scale, 0.5, 1e-12);
  EXPECT_LT(r2.ate.trans_m.max, 1e-12);
}

TEST(Ate, RotationErrorIsTheAngleOfTheRelativeRotation) {
  Trajectory gt = test::wavy_trajectory(10);
  Trajectory est = gt;
  for (auto& p : est.poses) p.q_WR = p.q_WR * test::exp_q(Eigen::Vector3d(0, 0, 0.1));
  EvalOptions o;
  o.align = Alignment::None;
  const EvalResult r = evaluate(est, gt, o);
  EXPECT_NEAR(r.ate.rot_deg.mean, 0.1 * 180 / M_PI, 1e-9);
  EXPECT_NEAR(r.ate.rot_deg.std, 0.0, 1e-9);
}

TEST(Ate, AgreesWithIndependentReferenceForEveryAlignment) {
  Rng rng(1234);
  const Trajectory gt = test::wavy_trajectory(300);
  Trajectory est = apply_alignment(test::random_sim3(rng, true), noisy_copy(gt, rng, 0.01, 0.01));
  for (Alignment a : {Alignment::Se3, Alignment::Sim3, Alignment::Origin, Alignment::None}) {
    EvalOptions o;
    o.align = a;
    const EvalResult r = evaluate(est, gt, o);
    Sim3 S;
    if (a == Alignment::Se3 || a == Alignment::Sim3) S = horn(est, gt, a == Alignment::Sim3);
    if (a == Alignment::Origin) {
      const Eigen::Isometry3d T = iso(gt.poses[0]) * iso(est.poses[0]).inverse();
      S.R = T.linear();
      S.t = T.translation();
    }
    std::vector<double> te, re;
    for (std::size_t i = 0; i < gt.poses.size(); ++i) {
      Eigen::Isometry3d P = iso(est.poses[i]);
      P.translation() = S.s * S.R * P.translation() + S.t;
      P.linear() = S.R * P.linear();
      const Eigen::Isometry3d E = P.inverse() * iso(gt.poses[i]);  // evo's APE: est⁻¹ · ref
      te.push_back((P.translation() - gt.poses[i].p_WR).norm());
      re.push_back(angle_deg(E.linear()));
    }
    double sse = 0, sum = 0;
    for (double e : te) { sse += e * e; sum += e; }
    std::sort(te.begin(), te.end());
    const double n = te.size();
    expect_rel(r.ate.trans_m.rmse, std::sqrt(sse / n), 1e-9, "rmse");
    expect_rel(r.ate.trans_m.mean, sum / n, 1e-9, "mean");
    expect_rel(r.ate.trans_m.median, 0.5 * (te[149] + te[150]), 1e-9, "median");
    expect_rel(r.ate.trans_m.max, te.back(), 1e-9, "max");
    double rsum = 0;
    for (double e : re) rsum += e;
    expect_rel(r.ate.rot_deg.mean, rsum / n, 1e-9, "rot mean");
  }
}

TEST(Rpe, AgreesWithIndependentReferenceInFramesAndMeters) {
  Rng rng(99);
  const Trajectory gt = test::wavy_trajectory(400);
  const Trajectory est = noisy_copy(gt, rng, 0.005, 0.005);
  for (const auto& [delta, unit] : {std::pair{1.0, DeltaUnit::Frames}, std::pair{10.0, DeltaUnit::Frames},
                                   std::pair{1.0, DeltaUnit::Meters}, std::pair{0.5, DeltaUnit::Seconds}}) {
    EvalOptions o;
    o.align = Alignment::None;
    o.rpe.delta = delta;
    o.rpe.unit = unit;
    const EvalResult r = evaluate(est, gt, o);
    ASSERT_TRUE(r.rpe) << r.rpe_error;
    // Independent pair selection.
    std::vector<std::size_t> ids;
    if (unit == DeltaUnit::Frames) {
      for (std::size_t i = 0; i < est.poses.size(); i += static_cast<std::size_t>(delta)) ids.push_back(i);
    } else if (unit == DeltaUnit::Meters) {
      double path = 0;
      for (std::size_t i = 0; i < est.poses.size(); ++i) {
        if (i) path += (est.poses[i].p_WR - est.poses[i - 1].p_WR).norm();
        if (path >= delta) { ids.push_back(i); path = 0; }
      }
    } else {
      ids.push_back(0);
      for (std::size_t i = 1; i < est.poses.size(); ++i)
        if (to_seconds(est.poses[i].t - est.poses[ids.back()].t) >= delta) ids.push_back(i);
    }
    ASSERT_EQ(r.rpe->pairs.size(), ids.size() - 1);
    double sse = 0, rot_sum = 0;
    for (std::size_t k = 0; k + 1 < ids.size(); ++k) {
      const std::size_t i = ids[k], j = ids[k + 1];
      EXPECT_EQ(r.rpe->pairs[k], std::make_pair(i, j));
      const Eigen::Isometry3d E = (iso(gt.poses[i]).inverse() * iso(gt.poses[j])).inverse() *
                                  (iso(est.poses[i]).inverse() * iso(est.poses[j]));
      sse += E.translation().squaredNorm();
      rot_sum += angle_deg(E.linear());
    }
    const double n = ids.size() - 1;
    expect_rel(r.rpe->trans_m.rmse, std::sqrt(sse / n), 1e-9, "rpe rmse");
    expect_rel(r.rpe->rot_deg.mean, rot_sum / n, 1e-9, "rpe rot mean");
  }
}

TEST(Rpe, AllPairsInFramesUsesEveryStartIndex) {
  const Trajectory gt = test::wavy_trajectory(25);
  RpeOptions o;
  o.delta = 5;
  o.all_pairs = true;
  const auto pairs = rpe_pairs(gt, o);
  ASSERT_EQ(pairs.size(), 20u);
  EXPECT_EQ(pairs.front(), (std::pair<std::size_t, std::size_t>{0, 5}));
  EXPECT_EQ(pairs.back(), (std::pair<std::size_t, std::size_t>{19, 24}));
  o.all_pairs = false;
  EXPECT_EQ(rpe_pairs(gt, o).size(), 4u);  // 0-5, 5-10, 10-15, 15-20
  o.delta = 100;
  EXPECT_THROW(rpe_pairs(gt, o), DataError);
}

TEST(Association, MatchesNearestStampWithinToleranceLikeEvo) {
  // Ground truth at 200 Hz, estimate at ~20 Hz with 1 ms jitter: every estimate pose finds the nearest truth.
  Rng rng(5);
  Trajectory gt = test::wavy_trajectory(2000, 200.0);
  Trajectory est;
  for (int i = 0; i < 180; ++i) {
    StampedPose p = gt.poses[10 * i + 3];
    p.t += from_seconds(randu(rng, -1e-3, 1e-3));
    est.poses.push_back(p);
  }
  const auto [e, g] = associate(est, gt, {});
  ASSERT_EQ(e.poses.size(), est.poses.size());
  for (std::size_t i = 0; i < e.poses.size(); ++i) {
    EXPECT_EQ(g.poses[i].t, gt.poses[10 * i + 3].t);
    EXPECT_EQ(e.poses[i].t, est.poses[i].t);
  }
  // A tight tolerance drops the poses farther than it from any truth stamp.
  const auto [e2, g2] = associate(est, gt, {.max_diff_s = 5e-4, .offset_s = 0.0});
  EXPECT_LT(e2.poses.size(), est.poses.size());
  for (std::size_t i = 0; i < e2.poses.size(); ++i) EXPECT_LE(std::llabs(e2.poses[i].t - g2.poses[i].t), 500'000);
}

TEST(Association, TiesTakeTheEarlierStampAndTheShorterTrajectoryDrives) {
  Trajectory gt, est;
  for (TimeNs t : {0, 10'000'000, 20'000'000}) gt.poses.push_back(at(t));
  est.poses.push_back(at(5'000'000));
  auto [e, g] = associate(est, gt, {});
  ASSERT_EQ(g.poses.size(), 1u);
  EXPECT_EQ(g.poses[0].t, 0);
  // Estimate longer than the truth: each truth pose picks one estimate pose (possibly the same one twice).
  Trajectory est_long;
  for (TimeNs t : {1'000'000, 2'000'000, 3'000'000, 4'000'000}) est_long.poses.push_back(at(t));
  Trajectory gt_short;
  for (TimeNs t : {0, 2'500'000}) gt_short.poses.push_back(at(t));
  auto [e3, g3] = associate(est_long, gt_short, {});
  ASSERT_EQ(e3.poses.size(), 2u);
  EXPECT_EQ(e3.poses[0].t, 1'000'000);
  EXPECT_EQ(e3.poses[1].t, 2'000'000);
}

TEST(Association, OffsetShiftsTheEstimate) {
  Trajectory gt = test::wavy_trajectory(100);
  Trajectory est = gt;
  for (auto& p : est.poses) p.t -= from_seconds(0.5);
  EXPECT_EQ(associate(est, gt, {.max_diff_s = 0.01, .offset_s = 0.5}).first.poses.size(), 100u);
  EXPECT_EQ(associate(est, gt, {.max_diff_s = 0.01, .offset_s = 0.0}).first.poses.size(), 90u);
}

TEST(Association, WithoutTimestampsIsByIndexAndNeedsEqualLengths) {
  Trajectory gt = test::wavy_trajectory(10);
  Trajectory est = gt;
  est.has_timestamps = false;
  EXPECT_EQ(associate(est, gt).first.poses.size(), 10u);
  est.poses.pop_back();
  EXPECT_THROW(associate(est, gt), DataError);
  Trajectory far = gt;
  for (auto& p : far.poses) p.t += from_seconds(100.0);
  EXPECT_THROW(associate(far, gt), DataError);
}

TEST(Association, AnEmptyTrajectoryIsNamedAsEmpty) {
  // It said "no matching timestamps", which sent users looking for a time offset.
  Trajectory gt = test::wavy_trajectory(10);
  gt.source = "gt.txt";
  Trajectory empty;
  empty.source = "out/trajectory.txt";
  for (const bool interpolate : {false, true}) {
    for (const bool estimate_empty : {true, false}) {
      try {
        associate(estimate_empty ? empty : gt, estimate_empty ? gt : empty, {.interpolate = interpolate});
        ADD_FAILURE() << "no error";
      } catch (const DataError& e) {
        EXPECT_NE(std::string(e.what()).find("out/trajectory.txt holds no pose (an empty trajectory)"),
                  std::string::npos)
            << e.what();
      }
    }
  }
  empty.has_timestamps = false;
  Trajectory gt_untimed = gt;
  gt_untimed.has_timestamps = false;
  EXPECT_THROW(associate(empty, gt_untimed), DataError);
}

TEST(Evaluate, TrajectoriesWithoutTimestampsHaveNoDuration) {
  // KITTI poses are numbered, not timed: their "duration" was the index span read as nanoseconds (0.00 s printed,
  // 1.99e-07 in the JSON).
  Trajectory gt = test::wavy_trajectory(40);
  for (std::size_t i = 0; i < gt.poses.size(); ++i) gt.poses[i].t = static_cast<TimeNs>(i);
  gt.has_timestamps = false;
  const EvalOptions o;
  const EvalResult r = evaluate(gt, gt, o);
  EXPECT_TRUE(std::isnan(r.duration_s));
  EXPECT_TRUE(to_json(r, o)["duration_s"].is_null());
  const std::string table = format_table(r, o);
  EXPECT_NE(table.find("40 matched; "), std::string::npos) << table;
  EXPECT_EQ(table.find(" s, "), std::string::npos) << table;
  EXPECT_GT(to_json(evaluate(test::wavy_trajectory(40), test::wavy_trajectory(40), o), o)["duration_s"].get<double>(),
            1.9);
}

// Ground truth sampled at 200 Hz, estimates at 20 Hz halfway between two samples: nearest-neighbour association
// pairs poses 2.5 ms apart (a position error of v·2.5 ms), interpolation evaluates the ground truth at the estimate's
// own time. On a trajectory that is linear in position and uniform in rotation between samples, the interpolated
// reference is exact.
TEST(Association, InterpolationEvaluatesTheReferenceAtTheEstimateTimes) {
  Trajectory gt;
  const Eigen::Vector3d v(1.0, -0.5, 0.2), w(0.1, 0.3, -0.2);
  auto pose_at = [&](TimeNs t) {
    StampedPose p;
    p.t = t;
    const double s = to_seconds(t);
    p.p_WR = v * s;
    p.q_WR = test::exp_q(w * s);
    return p;
  };
  for (int k = 0; k <= 400; ++k) gt.poses.push_back(pose_at(5'000'000LL * k));
  Trajectory est;
  for (int k = 0; k < 40; ++k) est.poses.push_back(pose_at(50'000'000LL * k + 2'500'000));
  const auto [e_near, g_near] = associate(est, gt, {.max_diff_s = 0.01});
  ASSERT_EQ(e_near.poses.size(), 40u);
  EXPECT_NEAR((e_near.poses[3].p_WR - g_near.poses[3].p_WR).norm(), v.norm() * 0.0025, 1e-12);
  const auto [e, g] = associate(est, gt, {.interpolate = true});
  ASSERT_EQ(e.poses.size(), 40u);
  for (std::size_t k = 0; k < e.poses.size(); ++k) {
    EXPECT_EQ(g.poses[k].t, e.poses[k].t);
    EXPECT_LT((e.poses[k].p_WR - g.poses[k].p_WR).norm(), 1e-12);
    EXPECT_LT(e.poses[k].q_WR.angularDistance(g.poses[k].q_WR), 1e-9);
  }
  // Estimates outside the reference's span, or in a gap larger than max_gap_s, are dropped.
  est.poses.push_back(pose_at(from_seconds(5.0)));
  Trajectory gapped = gt;
  gapped.poses.erase(gapped.poses.begin() + 100, gapped.poses.begin() + 140);  // 0.5..0.7 s missing
  const auto [e_gap, g_gap] = associate(est, gapped, {.interpolate = true, .max_gap_s = 0.1});
  EXPECT_EQ(e_gap.poses.size(), 40u - 4u);  // t = 0.5025 .. 0.6525 s fall into the 0.2 s gap; 5 s is outside
}

// A standstill's alignment rests on its jitter: the warning says so (and suggests the first-pose alignment when the
// rotation is the problem); a 20 s flight with 1 cm of noise is well determined and gets none.
TEST(AlignmentWarning, AStandstillIsFlaggedAndAFlightIsNot) {
  Rng rng(3);
  Trajectory gt, est;
  for (int i = 0; i < 95; ++i) {
    StampedPose p;
    p.t = 1'000'000'000 + i * 50'000'000LL;
    p.p_WR = randn_vec<3>(rng, 0.002);
    gt.poses.push_back(p);
    p.p_WR += randn_vec<3>(rng, 0.001);
    est.poses.push_back(p);
  }
  EvalOptions o;
  o.with_rpe = false;
  const EvalResult still = evaluate(est, gt, o);
  EXPECT_GT(still.alignment_rotation_std_deg, kMaxAlignmentRotationStdDeg);
  EXPECT_GT(still.sim3_scale_rel_std, kMaxAlignmentScaleStd);
  std::string w = alignment_warning(still);
  EXPECT_NE(w.find("its rotation is uncertain by"), std::string::npos) << w;
  EXPECT_NE(w.find("rtslam eval --align origin"), std::string::npos) << w;
  EXPECT_NE(format_table(still, o).find(w), std::string::npos);
  EXPECT_NE(evaluate_accuracy(est, gt, true).line.find(w), std::string::npos);  // rtslam run's accuracy lines
  const nlohmann::json j = to_json(still, o);
  EXPECT_DOUBLE_EQ(j["alignment"]["rotation_std_deg"].get<double>(), still.alignment_rotation_std_deg);
  EXPECT_DOUBLE_EQ(j["sim3_scale_rel_std"].get<double>(), still.sim3_scale_rel_std);
  o.align = Alignment::Origin;  // no rotation fitted: only the Sim(3) scale is flagged
  const EvalResult origin = evaluate(est, gt, o);
  w = alignment_warning(origin);
  EXPECT_NE(w.find("the Sim(3) scale is uncertain by"), std::string::npos) << w;
  EXPECT_EQ(w.find("--align origin"), std::string::npos) << w;
  EXPECT_TRUE(to_json(origin, o)["alignment"]["rotation_std_deg"].is_null());

  const Trajectory flight = test::wavy_trajectory(400);
  Trajectory noisy = flight;
  for (auto& p : noisy.poses) p.p_WR += randn_vec<3>(rng, 0.01);
  o.align = Alignment::Se3;
  const EvalResult moving = evaluate(noisy, flight, o);
  EXPECT_LT(moving.alignment_rotation_std_deg, 0.1);
  EXPECT_LT(moving.sim3_scale_rel_std, 0.001);
  EXPECT_TRUE(alignment_warning(moving).empty());
}
