// The odometry-driven robot in the System's loop (slam/odometry_robot.hpp): increments route to it by its input id,
// data wait until the increments cover them, the increment that straddles the start is applied from the start on,
// a straddling increment is split in proportion of time (mean and noise), and broken input streams are refused.
#include <cmath>
#include <utility>

#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/odometry_robot.hpp"
#include "rtslam/slam/sensor.hpp"
#include "rtslam/slam/system.hpp"
#include "slam/system_doubles.hpp"

namespace rtslam::slam {
namespace {


// Starts at the first datum offered, at the origin with zero covariance.
class OriginStarter final : public RobotStarter {
 public:
  std::optional<RobotStart> offer(const RawData& datum, const RingBuffer<ImuData>&) override {
    RobotStart s;
    s.x = Eigen::VectorXd::Zero(7);
    s.x(3) = 1.0;
    s.P = Eigen::MatrixXd::Zero(6, 6);
    s.t = datum.t;
    s.replay.push_back(&datum);
    return s;
  }
};

struct OdometryRig {
  World world;
  Map* map = nullptr;
  std::unique_ptr<System> system;
  CountingDataManager* dm = nullptr;
  Sensor* camera = nullptr;
  OdometryRobot* robot = nullptr;
  int input_id = -1;
  models::OdometryParams params;
  OdometryRig() {
    params.sigma_p = 0.1;
    params.sigma_theta = 0.2;
    params.k_p = 0.3;
    params.k_theta = 0.4;
    map = &world.add_map();
    system = std::make_unique<System>(world, *map, std::make_unique<NoMapManager>());
    auto r = std::make_unique<OdometryRobot>(params);
    robot = r.get();
    models::CameraIntrinsics c;
    c.width = 640;
    c.height = 480;
    c.fx = c.fy = 400.0;
    c.cx = 320.0;
    c.cy = 240.0;
    camera = &r->add_sensor(std::make_unique<PinholeSensor>("cam0", c, math::Pose{}));
    auto d = std::make_unique<CountingDataManager>();
    dm = d.get();
    camera->set_data_manager(std::move(d));
    input_id = system->add_robot(std::move(r), std::make_unique<OriginStarter>());
  }
  // The increment (t - 10 ms, t]: dp forward along x, dyaw about z.
  void odometry(TimeNs t, double dp, double dyaw) {
    auto d = system->spare<OdometryData>();
    d->t = t;
    d->t_from = t - 10 * kNsPerMs;
    d->sensor_id = input_id;
    d->dp = Eigen::Vector3d(dp, 0.0, 0.0);
    d->dtheta = Eigen::Vector3d(0.0, 0.0, dyaw);
    system->feed(std::move(d));
  }
  void image(TimeNs t) {
    auto d = system->spare<Blob>();
    d->t = t;
    d->sensor_id = camera->id();
    system->feed(std::move(d));
  }
};

TEST(OdometryRobot, DataWaitUntilTheIncrementsCoverThem) {
  OdometryRig rig;
  rig.odometry(10 * kNsPerMs, 0.01, 0.0);
  rig.image(15 * kNsPerMs);
  EXPECT_EQ(rig.system->pending(), 1u);
  EXPECT_TRUE(rig.dm->times.empty());
  rig.odometry(20 * kNsPerMs, 0.01, 0.0);
  EXPECT_EQ(rig.system->pending(), 0u);
  EXPECT_EQ(rig.dm->times, std::vector<TimeNs>{15 * kNsPerMs});
}

TEST(OdometryRobot, StraddlingIncrementsAreSplitInProportionOfTime) {
  OdometryRig rig;
  for (TimeNs t = 10 * kNsPerMs; t <= 30 * kNsPerMs; t += 10 * kNsPerMs) rig.odometry(t, 0.01, 0.02);
  rig.image(25 * kNsPerMs);  // the start, inside (20, 30]: its last half is applied from the start on
  for (TimeNs t = 40 * kNsPerMs; t <= 60 * kNsPerMs; t += 10 * kNsPerMs) rig.odometry(t, 0.01, 0.02);
  rig.image(55 * kNsPerMs);
  ASSERT_EQ(rig.dm->times.size(), 2u);
  // From 25 to 55 ms: three increments' worth, 0.03 m and 0.06 rad, along an arc.
  const math::Pose T = rig.robot->pose();
  EXPECT_NEAR(math::log_so3(T.q).z(), 0.06, 1e-12);
  EXPECT_NEAR(T.p.norm(), 0.03, 1e-5);
  // Each part of an increment moves along the robot's x axis at the part's start: yaw 0, 0.01, 0.03, 0.05 rad.
  Eigen::Vector3d p_expected = Eigen::Vector3d::Zero();
  for (const auto& [len, yaw] : {std::pair{0.005, 0.0}, {0.01, 0.01}, {0.01, 0.03}, {0.005, 0.05}}) {
    p_expected += len * Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0.0);
  }
  EXPECT_LT((T.p - p_expected).norm(), 1e-15);
  // Noise: 30 ms of densities plus 0.03 m and 0.06 rad of motion (started with zero covariance; to first order,
  // the rotation's noise also spreads the position).
  const Eigen::MatrixXd P = rig.map->state().cov(rig.robot->block());
  const auto& p = rig.params;
  EXPECT_NEAR(P(5, 5), p.sigma_theta * p.sigma_theta * 0.03 + p.k_theta * p.k_theta * 0.06, 1e-12);
  EXPECT_NEAR(P(0, 0), p.sigma_p * p.sigma_p * 0.03 + p.k_p * p.k_p * 0.03, 1e-6);
  EXPECT_EQ(rig.robot->increments_applied(), 4);  // half, two whole, half
}

TEST(OdometryRobot, BrokenInputStreamsAreRefused) {
  OdometryRig rig;
  rig.odometry(10 * kNsPerMs, 0.01, 0.0);
  auto overlapping = rig.system->spare<OdometryData>();
  overlapping->t = 15 * kNsPerMs;
  overlapping->t_from = 5 * kNsPerMs;
  overlapping->sensor_id = rig.input_id;
  rig.image(8 * kNsPerMs);  // starts the robot
  EXPECT_THROW(rig.system->feed(std::move(overlapping)), DataError);
  auto imu = rig.system->spare<ImuData>();
  imu->t = 30 * kNsPerMs;
  imu->sensor_id = rig.input_id;
  EXPECT_THROW(rig.system->feed(std::move(imu)), DataError);
  rig.odometry(30 * kNsPerMs, 0.01, 0.0);  // (20, 30]: the gap (10, 20] is no motion
  rig.image(25 * kNsPerMs);
  EXPECT_NEAR(rig.robot->pose().p.x(), 0.002 + 0.005, 1e-12);  // (8, 10] and (20, 25]
}

}  // namespace
}  // namespace rtslam::slam
