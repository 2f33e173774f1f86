// The health monitor's verdicts on hand-made frames: non-finite and implausible states diverge at once, too few
// corrections for lost_after_s is "lost" (not during the grace period after a start, and counted afresh after an
// image gap), and a window of matches at the edge of their ellipses is "diverged".
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
