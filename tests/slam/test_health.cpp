// The health monitor's verdicts on hand-made frames: non-finite and implausible states diverge at once, too few
// corrections for lost_after_s is "lost" (not during the grace period after a start, and counted afresh after an
// image gap), a window of matches at the edge of their ellipses is "diverged", and a quarter second of frames whose
// matches one-point RANSAC could not explain with one hypothesis is "lost".
#include <gtest/gtest.h>

#include <limits>

#include "rtslam/slam/health.hpp"
#include "rtslam/slam/map.hpp"

namespace rtslam::slam {
namespace {

struct Fixture {
  World world;
  Map& map = world.add_map();
  Robot* robot = nullptr;
  Fixture() {
    Eigen::VectorXd x = Eigen::VectorXd::Zero(13);
    x[3] = 1.0;
    Eigen::MatrixXd P = Eigen::MatrixXd::Identity(12, 12) * 0.01;
    robot = &map.add_robot(std::make_unique<ConstantVelocityRobot>(models::ConstantVelocityParams{}), x, P, 0);
  }
};

FrameStats frame(double t_s, int updated, double nis = 0.0, int nis_count = 0) {
  FrameStats s;
  s.t = from_seconds(t_s);
  s.updated = updated;
  s.matched = updated;
  s.nis = nis;
  s.nis_count = nis_count;
  return s;
}

TEST(HealthMonitor, TracksWhileCorrectionsComeAndIsLostAfterTheirAbsence) {
  Fixture f;
  HealthMonitor m(HealthOptions{});
  m.restart(0);
  for (int k = 0; k <= 40; ++k) EXPECT_EQ(m.check(f.map, *f.robot, frame(0.05 * k, 20)).health, Health::Ok);
  // No correction from 2.05 s on: lost once 0.5 s have passed without one.
  EXPECT_EQ(m.check(f.map, *f.robot, frame(2.05, 1)).health, Health::Ok);
  EXPECT_EQ(m.check(f.map, *f.robot, frame(2.45, 0)).health, Health::Ok);
  const auto v = m.check(f.map, *f.robot, frame(2.50, 0));
  EXPECT_EQ(v.health, Health::Lost);
  EXPECT_NE(v.reason.find("fewer than 3 corrections"), std::string::npos) << v.reason;
}

TEST(HealthMonitor, NoLostVerdictDuringTheGracePeriodAfterAStart) {
  Fixture f;
  HealthMonitor m(HealthOptions{});
  m.restart(from_seconds(10.0));
  for (int k = 0; k < 19; ++k) EXPECT_EQ(m.check(f.map, *f.robot, frame(10.0 + 0.05 * k, 0)).health, Health::Ok);
  // The grace period (1 s) over: the lost timer starts at its end.
  EXPECT_EQ(m.check(f.map, *f.robot, frame(11.2, 0)).health, Health::Ok);
  EXPECT_EQ(m.check(f.map, *f.robot, frame(11.6, 0)).health, Health::Lost);
}

TEST(HealthMonitor, AnImageGapIsNotedAndTheLostTimerStartsAfterIt) {
  Fixture f;
  HealthMonitor m(HealthOptions{});
  m.restart(0);
  for (int k = 0; k <= 40; ++k) m.check(f.map, *f.robot, frame(0.05 * k, 20));
  const auto v = m.check(f.map, *f.robot, frame(4.0, 0));  // 2 s blackout
  EXPECT_EQ(v.health, Health::Ok);
  EXPECT_NE(v.note.find("no image for 2.00 s"), std::string::npos) << v.note;
  EXPECT_EQ(m.frame_gaps(), 1);
  EXPECT_EQ(m.check(f.map, *f.robot, frame(4.45, 0)).health, Health::Ok);
  EXPECT_EQ(m.check(f.map, *f.robot, frame(4.5, 0)).health, Health::Lost);
}

TEST(HealthMonitor, NonFiniteOrImplausibleStatesDivergeAtOnce) {
  {
    Fixture f;
    HealthMonitor m(HealthOptions{});
    m.restart(0);
    f.map.state().mean(f.robot->block())[0] = std::numeric_limits<double>::quiet_NaN();
    const auto v = m.check(f.map, *f.robot, frame(0.05, 20));
    EXPECT_EQ(v.health, Health::Diverged);
    EXPECT_NE(v.reason.find("not finite"), std::string::npos);
  }
  {
    Fixture f;
    HealthMonitor m(HealthOptions{});
    m.restart(0);
    f.map.state().mean(f.robot->block())[7] = 80.0;  // v_x
    const auto v = m.check(f.map, *f.robot, frame(0.05, 20));
    EXPECT_EQ(v.health, Health::Diverged);
    EXPECT_NE(v.reason.find("speed 80.0 m/s"), std::string::npos) << v.reason;
  }
}

TEST(HealthMonitor, MatchesAtTheEdgeOfTheirEllipsesOverAWindowDiverge) {
  Fixture f;
  HealthMonitor m(HealthOptions{});
  m.restart(0);
  // Consistent innovations: NIS 2 per match (1 per dof).
  for (int k = 0; k <= 60; ++k) EXPECT_EQ(m.check(f.map, *f.robot, frame(0.05 * k, 20, 40.0, 20)).health, Health::Ok);
  // Every match near the 3σ gate (NIS ≈ 8.5 per match): the window mean crosses 3.5 per dof.
  Health h = Health::Ok;
  for (int k = 61; k <= 90 && h == Health::Ok; ++k) h = m.check(f.map, *f.robot, frame(0.05 * k, 20, 170.0, 20)).health;
  EXPECT_EQ(h, Health::Diverged);
}

// A frame whose one-point RANSAC ran (cap 22) with `matched` matches of which `inliers` supported its best hypothesis.
FrameStats ransac_frame(double t_s, int matched, int inliers) {
  FrameStats s = frame(t_s, matched);
  s.ransac_max = 22;
  s.ransac_inliers = inliers;
  return s;
}

TEST(HealthMonitor, MatchesThatNoSingleMotionExplainsForAQuarterSecondAreLost) {
  Fixture f;
  HealthMonitor m(HealthOptions{});
  m.restart(0);
  for (int k = 0; k <= 40; ++k) EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(0.05 * k, 25, 22)).health, Health::Ok);
  // Low-consensus frames alone, or with fewer than 10 matches, or without RANSAC, do not add up to a verdict.
  for (int k = 41; k <= 80; ++k) {
    FrameStats s = k % 2 == 0 ? ransac_frame(0.05 * k, 25, 4) : ransac_frame(0.05 * k, 25, 20);
    if (k % 5 == 0) s = ransac_frame(0.05 * k, 9, 1);  // too few matches to judge
    if (k % 7 == 0) s = frame(0.05 * k, 25);           // RANSAC did not run (ransac_max 0)
    EXPECT_EQ(m.check(f.map, *f.robot, s).health, Health::Ok) << k;
  }
  EXPECT_FALSE(m.suspect());  // frame 79 (20 of 25) ended the last streak; frame 80 was not judged
  // The threshold: 35 % of min(25 matched, cap 22) = 7.7 inliers. From 4.25 s on, every judged frame is low; frames
  // that are not judged neither extend nor end the streak: lost at 4.50 s, 0.25 s after its first frame.
  EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(4.20, 25, 8)).health, Health::Ok);
  EXPECT_FALSE(m.suspect());
  EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(4.25, 25, 7)).health, Health::Ok);
  EXPECT_TRUE(m.suspect());  // the last healthy state stops following the estimate
  EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(4.30, 25, 3)).health, Health::Ok);
  EXPECT_EQ(m.check(f.map, *f.robot, frame(4.35, 25)).health, Health::Ok);
  EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(4.40, 8, 1)).health, Health::Ok);
  EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(4.45, 12, 2)).health, Health::Ok);  // min(12, 22) * 0.35 = 4.2
  const auto v = m.check(f.map, *f.robot, ransac_frame(4.50, 25, 5));
  EXPECT_EQ(v.health, Health::Lost);
  EXPECT_NE(v.reason.find("one-point RANSAC explained fewer than 35 % of the matches"), std::string::npos) << v.reason;
  EXPECT_NE(v.reason.find("5 of 25"), std::string::npos) << v.reason;
  // A restart forgets the streak; min_consensus 0 turns the judgment off.
  m.restart(from_seconds(5.0));
  EXPECT_FALSE(m.suspect());
  HealthOptions off;
  off.min_consensus = 0.0;
  HealthMonitor n(off);
  n.restart(0);
  for (int k = 0; k <= 60; ++k) EXPECT_EQ(n.check(f.map, *f.robot, ransac_frame(0.05 * k, 25, 2)).health, Health::Ok);
}

TEST(HealthMonitor, AConsensusStreakNeedsJudgedFramesAndAnImageGapEndsIt) {
  // Review 28 Nov: frames not judged let the streak's clock run out, and a streak went on across an image gap.
  Fixture f;
  HealthMonitor m(HealthOptions{});
  m.restart(0);
  for (int k = 0; k <= 40; ++k) EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(0.05 * k, 25, 22)).health, Health::Ok);
  EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(2.05, 25, 3)).health, Health::Ok);
  EXPECT_TRUE(m.suspect());
  // Then only frames with 9 matches (not judged): no verdict, and after lost_after (0.5 s) without a judged frame
  // the streak ends.
  for (int k = 42; k <= 50; ++k) {
    EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(0.05 * k, 9, 0)).health, Health::Ok) << k;
    EXPECT_TRUE(m.suspect()) << k;
  }
  EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(2.55, 9, 0)).health, Health::Ok);
  EXPECT_FALSE(m.suspect());
  // A frame whose search ran out of its time budget is not judged either.
  EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(2.60, 25, 3)).health, Health::Ok);
  for (int k = 53; k <= 60; ++k) {
    FrameStats s = ransac_frame(0.05 * k, 25, 3);
    s.budget_hit = true;
    EXPECT_EQ(m.check(f.map, *f.robot, s).health, Health::Ok) << k;
  }
  // An image gap (0.75 s) ends the streak: the first frame after it starts a new one, lost 0.25 s later.
  const auto after_gap = m.check(f.map, *f.robot, ransac_frame(3.75, 25, 3));
  EXPECT_EQ(after_gap.health, Health::Ok);
  EXPECT_FALSE(after_gap.note.empty());
  for (int k = 76; k <= 79; ++k) EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(0.05 * k, 25, 3)).health, Health::Ok);
  EXPECT_EQ(m.check(f.map, *f.robot, ransac_frame(4.00, 25, 3)).health, Health::Lost);
}

TEST(HealthOptions, BoundsAreCheckedWithTheKeyNamed) {
  HealthOptions o;
  o.lost_after_s = 0.0;
  try {
    o.validate();
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("lost_after"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rtslam::slam
