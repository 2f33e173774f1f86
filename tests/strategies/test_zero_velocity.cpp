// Zero-velocity updates (strategies/zero_velocity.hpp): the image test, one update against the closed-form Kalman
// step, once per robot and time (a stereo pair), each robot with its own options, the verdict's hold, refusals.
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/odometry_robot.hpp"
#include "rtslam/slam/system.hpp"
#include "rtslam/slam/robot.hpp"
#include "rtslam/slam/sensor.hpp"
#include "support/test_camera.hpp"
#include "rtslam/strategies/zero_velocity.hpp"

namespace rtslam::strategies {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using Match = ActiveSearchDataManager::FrameMatch;

// A constant-velocity robot (tangent [δp δθ v ω]; no inputs: judged by the images alone) moving at v0 and ω0, with
// variance var on v and ω.
struct MovingRobot {
  slam::World world;
  slam::Map* map = nullptr;
  slam::Robot* robot = nullptr;
  MovingRobot(const Vector3d& v0, const Vector3d& w0, double var) {
    map = &world.add_map();
    Eigen::VectorXd x0 = Eigen::VectorXd::Zero(13);
    x0[3] = 1.0;  // q = identity (w x y z)
    x0.segment<3>(7) = v0;
    x0.segment<3>(10) = w0;
    Eigen::MatrixXd P = Eigen::MatrixXd::Zero(12, 12);
    P.diagonal().head<6>().setConstant(0.01);
    P.diagonal().tail<6>().setConstant(var);
    auto owned = std::make_unique<slam::ConstantVelocityRobot>(models::ConstantVelocityParams{});
    for (const char* name : {"cam0", "cam1"}) {
      owned->add_sensor(std::make_unique<slam::PinholeSensor>(name, support::vga_camera(), math::Pose{}));
    }
    robot = &map->add_robot(std::move(owned), x0, P, 0);
  }
  /// The map's id of camera k (0, 1).
  int cam(int k) const { return robot->sensors().at(static_cast<std::size_t>(k))->id(); }
  Vector3d v() const { return map->state().mean(robot->block()).segment<3>(7); }
  Vector3d w() const { return map->state().mean(robot->block()).segment<3>(10); }
  double var_v() const { return map->state().cov(robot->block(), robot->block())(6, 6); }
};

// n landmarks (ids 0..n-1) matched on a grid, all shifted by `shift` px.
std::vector<Match> matched(int n, const Vector2d& shift) {
  std::vector<Match> out(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    Match& m = out[static_cast<std::size_t>(i)];
    m.landmark_id = i;
    m.searched = m.matched = true;
    m.z = Vector2d(40.0 * (i % 8), 30.0 * (i / 8)) + shift;
  }
  return out;
}

constexpr TimeNs kMs = 1'000'000;

struct Feed {
  ZeroVelocityUpdater u;
  RingBuffer<slam::ImuData> no_inputs{4};
  slam::FrameStats stats;
  void image(MovingRobot& r, int sensor_id, TimeNs t, const std::vector<Match>& matches) {
    stats = slam::FrameStats{};
    u.after_image(*r.map, *r.robot, sensor_id, t, matches, no_inputs, stats);
  }
};

TEST(ZeroVelocity, StillImagesGiveOneUpdateATimeThatIsTheClosedFormKalmanStep) {
  const Vector3d v0(0.02, -0.01, 0.005), w0(0.01, 0.0, -0.02);
  const double var = 1e-4;
  MovingRobot r(v0, w0, var);
  ZeroVelocityOptions o;
  o.velocity_std = 0.003;
  Feed run;
  run.u.add_robot(*r.robot, o);
  // A stereo pair (sensors 0 and 1): the first time has no previous frame to compare with.
  run.image(r, r.cam(0), 0, matched(12, Vector2d::Zero()));
  run.image(r, r.cam(1), 0, matched(12, Vector2d(-30.0, 0.0)));
  EXPECT_EQ(run.u.updates(), 0);
  EXPECT_LT(run.u.last_disparity_px(), 0.0);
  // 50 ms later, both images moved by 0.1 px (below 0.3): at rest; the first image of the time updates.
  run.image(r, r.cam(0), 50 * kMs, matched(12, Vector2d(0.1, 0.0)));
  EXPECT_NEAR(run.u.last_disparity_px(), 0.1, 1e-12);
  EXPECT_TRUE(run.stats.zero_velocity);
  EXPECT_EQ(run.u.updates(), 1);
  // Each of v and ω is a scalar Kalman step (independent, measured directly): x ← x r / (var + r).
  const double rv = o.velocity_std * o.velocity_std, keep = rv / (var + rv);  // 1 − K
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(r.v()[i], v0[i] * keep, 1e-15);
    EXPECT_NEAR(r.w()[i], w0[i] * keep, 1e-15);
  }
  EXPECT_NEAR(r.var_v(), var * rv / (var + rv), 1e-15);
  // The same time's second image also says at rest: the robot was told already (a second update would halve the
  // variance again).
  run.image(r, r.cam(1), 50 * kMs, matched(12, Vector2d(-29.9, 0.0)));
  EXPECT_FALSE(run.stats.zero_velocity);
  EXPECT_EQ(run.u.updates(), 1);
  EXPECT_NEAR(r.var_v(), var * rv / (var + rv), 1e-15);
  // The next time updates again.
  run.image(r, r.cam(0), 100 * kMs, matched(12, Vector2d(0.1, 0.0)));
  EXPECT_EQ(run.u.updates(), 2);
  run.image(r, r.cam(1), 100 * kMs, matched(12, Vector2d(-29.9, 0.0)));
  // The robot's verdict is the latest judged by any of its cameras: the left one now sees motion, the right one has
  // too few matches to judge; its own earlier "still" does not hold the robot at rest.
  run.image(r, r.cam(0), 150 * kMs, matched(12, Vector2d(1.5, 0.0)));
  run.image(r, r.cam(1), 150 * kMs, matched(4, Vector2d(-29.9, 0.0)));
  EXPECT_EQ(run.u.updates(), 2);
}

TEST(ZeroVelocity, ARestartForgetsTheVerdictAndThePreviousFrames) {
  MovingRobot r(Vector3d(0.01, 0.0, 0.0), Vector3d::Zero(), 1e-4);
  Feed run;
  run.u.add_robot(*r.robot, ZeroVelocityOptions{});
  run.image(r, r.cam(0), 0, matched(12, Vector2d::Zero()));
  run.image(r, r.cam(1), 0, matched(12, Vector2d(-30.0, 0.0)));
  run.image(r, r.cam(0), 50 * kMs, matched(12, Vector2d::Zero()));
  EXPECT_EQ(run.u.updates(), 1);
  // The health monitor restarts the robot at 50 ms and replays the pair's other image (System::start): neither the
  // rest seen before the restart nor the frames before it are the new robot's.
  run.u.on_start(*r.robot, slam::RobotStart{});
  run.image(r, r.cam(1), 50 * kMs, matched(12, Vector2d(-30.0, 0.0)));
  run.image(r, r.cam(0), 100 * kMs, matched(12, Vector2d::Zero()));  // the first frame of each since: no verdict
  EXPECT_EQ(run.u.updates(), 1);
  run.image(r, r.cam(0), 150 * kMs, matched(12, Vector2d::Zero()));
  EXPECT_EQ(run.u.updates(), 2);
}

// The inertial robot [p q v ab wb g]: judged by the images and the IMU; only v is measured (3 rows).
TEST(ZeroVelocity, TheInertialRobotIsUpdatedOnItsVelocityOnlyAndOnlyWhenTheImuIsAtRestToo) {
  const auto make = [](slam::Map& map) -> slam::Robot& {
    Eigen::VectorXd x0 = Eigen::VectorXd::Zero(19);
    x0[3] = 1.0;                                 // q = identity
    x0.segment<3>(7) << 0.02, -0.01, 0.005;      // v
    x0.segment<3>(10) << 0.05, 0.0, -0.02;       // accelerometer bias
    x0.segment<3>(13) << 0.001, 0.002, 0.0;      // gyro bias
    x0.segment<3>(16) << 0.0, 0.0, -9.81;        // g
    Eigen::MatrixXd P = 1e-3 * Eigen::MatrixXd::Identity(18, 18);
    P.diagonal().segment<3>(6).setConstant(1e-4);
    return map.add_robot(std::make_unique<slam::InertialRobot>(models::InertialParams{}), x0, P, 0);
  };
  // 200 Hz over 0.6 s: at rest (constant readings with a 1 mrad/s, 0.05 m/s² sample-to-sample ripple, which the 25 ms
  // block means average out) or shaken (±0.5 rad/s and ±2 m/s² swings every 100 ms).
  const auto imu = [](bool shaken) {
    RingBuffer<slam::ImuData> b(256);
    for (int k = 0; k <= 120; ++k) {
      slam::ImuData d;
      d.t = k * 5 * kMs;
      const double ripple = k % 2 == 0 ? 1.0 : -1.0;
      const double swing = shaken ? (k % 40 < 20 ? 1.0 : -1.0) : 0.0;
      d.m.gyro = Vector3d(1e-3 * ripple + 0.5 * swing, 0.0, 0.0);
      d.m.accel = Vector3d(0.0, 0.05 * ripple + 2.0 * swing, 9.81);
      b.push_back(d);
    }
    return b;
  };
  for (const bool shaken : {false, true}) {
    slam::World world;
    slam::Map& map = world.add_map();
    slam::Robot& robot = make(map);
    const Eigen::VectorXd x_before = map.state().mean(robot.block());
    ZeroVelocityOptions o;
    ZeroVelocityUpdater u;
    u.add_robot(robot, o);
    const RingBuffer<slam::ImuData> inputs = imu(shaken);
    slam::FrameStats stats;
    u.after_image(map, robot, 0, 500 * kMs, matched(12, Vector2d::Zero()), inputs, stats);
    u.after_image(map, robot, 0, 550 * kMs, matched(12, Vector2d::Zero()), inputs, stats);
    const Eigen::VectorXd x = map.state().mean(robot.block());
    if (shaken) {
      EXPECT_EQ(u.updates(), 0);
      EXPECT_EQ(x, x_before);
      continue;
    }
    ASSERT_EQ(u.updates(), 1);
    const double rv = o.velocity_std * o.velocity_std, keep = rv / (1e-4 + rv);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(x[7 + i], x_before[7 + i] * keep, 1e-15);
    EXPECT_EQ(x.head<7>(), x_before.head<7>());
    EXPECT_EQ(x.tail<9>(), x_before.tail<9>());  // biases and g: uncorrelated with v here, untouched
    EXPECT_NEAR(map.state().cov(robot.block(), robot.block())(6, 6), 1e-4 * keep, 1e-15);
  }
}

TEST(ZeroVelocity, MovingImagesNoUpdateAndTooFewMatchesKeepTheVerdictForTheWindow) {
  MovingRobot r(Vector3d(0.5, 0.0, 0.0), Vector3d::Zero(), 1e-2);
  ZeroVelocityOptions o;  // window 0.5 s, max_disparity_px 0.3, min_matches 10
  Feed run;
  run.u.add_robot(*r.robot, o);
  run.image(r, r.cam(0), 0, matched(12, Vector2d::Zero()));
  run.image(r, r.cam(0), 50 * kMs, matched(12, Vector2d(1.0, 0.0)));  // 1 px: moving
  EXPECT_NEAR(run.u.last_disparity_px(), 1.0, 1e-12);
  EXPECT_EQ(run.u.updates(), 0);
  EXPECT_EQ(r.v().x(), 0.5);
  // Still again, then 5 matches only (too few to judge): the still verdict of 100 ms holds up to the window.
  run.image(r, r.cam(0), 100 * kMs, matched(12, Vector2d(1.0, 0.0)));
  EXPECT_EQ(run.u.updates(), 1);
  run.image(r, r.cam(0), 400 * kMs, matched(5, Vector2d(1.0, 0.0)));
  EXPECT_LT(run.u.last_disparity_px(), 0.0);
  EXPECT_EQ(run.u.updates(), 2);
  run.image(r, r.cam(0), 700 * kMs, matched(5, Vector2d(1.0, 0.0)));  // 0.6 s after the verdict: no longer
  EXPECT_EQ(run.u.updates(), 2);
  // 12 matches after a frame of 5: only 5 have a previous pixel, still no verdict; the next frame judges again.
  run.image(r, r.cam(0), 750 * kMs, matched(12, Vector2d(1.0, 0.0)));
  EXPECT_EQ(run.u.updates(), 2);
  run.image(r, r.cam(0), 800 * kMs, matched(12, Vector2d(1.0, 0.0)));
  EXPECT_EQ(run.u.updates(), 3);
  // A moving verdict stops the updates at once.
  run.image(r, r.cam(0), 850 * kMs, matched(12, Vector2d(2.0, 0.5)));
  EXPECT_EQ(run.u.updates(), 3);
}

TEST(ZeroVelocity, EachRobotWithItsOwnOptionsAndARobotNotAddedIsLeftAlone) {
  const Vector3d v0(0.01, 0.0, 0.0);
  MovingRobot a(v0, Vector3d::Zero(), 1e-4), b(v0, Vector3d::Zero(), 1e-4), c(v0, Vector3d::Zero(), 1e-4);
  ZeroVelocityOptions oa, ob;
  oa.velocity_std = 0.01;
  ob.min_matches = 20;  // more than the 12 matched: b's images are never judged
  Feed run;
  run.u.add_robot(*a.robot, oa);
  run.u.add_robot(*b.robot, ob);
  // Each robot here has a map of its own; in a System they share one, whose sensor ids are distinct: so are these.
  for (const TimeNs t : {TimeNs{0}, 50 * kMs}) {
    run.image(a, 0, t, matched(12, Vector2d::Zero()));
    run.image(b, 1, t, matched(12, Vector2d::Zero()));
    run.image(c, 2, t, matched(12, Vector2d::Zero()));
  }
  EXPECT_EQ(run.u.updates(), 1);
  const double rv = oa.velocity_std * oa.velocity_std;
  EXPECT_NEAR(a.v().x(), v0.x() * rv / (1e-4 + rv), 1e-15);  // a's own std, not the default 0.002
  EXPECT_EQ(b.v().x(), v0.x());
  EXPECT_EQ(c.v().x(), v0.x());
}

TEST(ZeroVelocity, ARefusedUpdateIsCountedAndChangesNothing) {
  const Vector3d v0(0.01, 0.0, 0.0);
  MovingRobot r(v0, Vector3d::Zero(), 1e-4);
  Feed run;
  run.u.add_robot(*r.robot, ZeroVelocityOptions{});
  run.image(r, r.cam(0), 0, matched(12, Vector2d::Zero()));
  run.image(r, r.cam(1), 0, matched(12, Vector2d(-30.0, 0.0)));
  // A broken covariance (a negative velocity variance): S is not positive definite and the filter refuses.
  r.map->state().cov(r.robot->block(), r.robot->block())(6, 6) = -1.0;
  run.image(r, r.cam(0), 50 * kMs, matched(12, Vector2d::Zero()));
  EXPECT_EQ(run.u.updates(), 0);
  EXPECT_EQ(run.u.refused(), 1);
  EXPECT_FALSE(run.stats.zero_velocity);
  EXPECT_EQ(r.v(), v0);
  // Nothing was told at that time: the same time's other image tries again; so does the next time.
  run.image(r, r.cam(1), 50 * kMs, matched(12, Vector2d(-30.0, 0.0)));
  EXPECT_EQ(run.u.refused(), 2);
  run.image(r, r.cam(0), 100 * kMs, matched(12, Vector2d::Zero()));
  EXPECT_EQ(run.u.refused(), 3);
  EXPECT_EQ(run.u.updates(), 0);
}

TEST(ZeroVelocity, ARobotWithoutVelocityInItsStateIsRefusedWhenAdded) {
  slam::World world;
  slam::Map& map = world.add_map();
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(7);
  x0[3] = 1.0;
  slam::Robot& odo = map.add_robot(std::make_unique<slam::OdometryRobot>(models::OdometryParams{}), x0,
                                   Eigen::MatrixXd::Identity(6, 6), 0);
  ZeroVelocityUpdater u;
  try {
    u.add_robot(odo, ZeroVelocityOptions{});
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("zero_velocity: robot 'robot' has no velocity"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(slam::InertialRobot(models::InertialParams{}).rest_rows(), 3);  // v (not the biases, not g)
  EXPECT_EQ(slam::ConstantVelocityRobot(models::ConstantVelocityParams{}).rest_rows(), 6);  // v and ω
}

}  // namespace
}  // namespace rtslam::strategies
