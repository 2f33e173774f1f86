// The odometry-driven robot in the System's loop (slam/odometry_robot.hpp): increments route to it by its input id,
// data wait until the increments cover them, the increment that straddles the start is applied from the start on,
// a straddling increment is split in proportion of time (mean and noise), and broken input streams are refused;
// the map's scale is kept at the odometry's (OdometryScaleOptions, Map::scale_lengths).
#include <cmath>
#include <utility>

#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/landmark_init.hpp"
#include "rtslam/slam/odometry_robot.hpp"
#include "rtslam/slam/sensor.hpp"
#include "rtslam/slam/system.hpp"
#include "slam/system_doubles.hpp"
#include "support/test_camera.hpp"

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
  explicit OdometryRig(OdometryScaleOptions scale = {}) {
    params.sigma_p = 0.1;
    params.sigma_theta = 0.2;
    params.k_p = 0.3;
    params.k_theta = 0.4;
    map = &world.add_map();
    system = std::make_unique<System>(*map, std::make_unique<NoMapManager>());
    auto r = std::make_unique<OdometryRobot>(params, "robot", scale);
    robot = r.get();
    camera = &r->add_sensor(std::make_unique<PinholeSensor>("cam0", support::vga_camera(), math::Pose{}));
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

// Starts the rig's robot at the origin at 10 ms.
void start(OdometryRig& rig) {
  rig.odometry(10 * kNsPerMs, 0.01, 0.0);
  rig.image(10 * kNsPerMs);
}

// Drives the started rig 1 m/s straight ahead for `seconds`, images at 20 Hz, as a filter whose path comes out
// `stretch` times the odometry's (as the monocular EKF's map scale makes it, docs/odometry-scale.md) until the map
// is first rescaled; returns the distance travelled then (0: never).
double drive_stretched(OdometryRig& rig, double stretch, double seconds) {
  constexpr TimeNs kStep = 10 * kNsPerMs;
  double dead_reckoning = 0.0;
  for (TimeNs t = 2 * kStep; t <= static_cast<TimeNs>(seconds * 100.0) * kStep; t += kStep) {
    rig.odometry(t, 0.01, 0.0);
    dead_reckoning += 0.01;
    if (t % (5 * kStep) != 0) continue;
    rig.image(t);
    if (rig.robot->rescales() > 0) return dead_reckoning;
    rig.map->state().mean(rig.robot->block())[0] = stretch * dead_reckoning;
  }
  return 0.0;
}

// The robot compares its windows of odometry with its estimated displacements and changes the map's unit of length
// by the least-squares factor, 0.8, once its standard error is small enough; the landmarks scale with it.
TEST(OdometryRobot, KeepsTheMapAtTheOdometryScale) {
  OdometryRig rig(OdometryScaleOptions{.enabled = true, .window_m = 0.5, .max_se = 0.2, .min_z = 0.0});
  start(rig);
  Landmark* ahp = init_ahp_landmark(*rig.map, *rig.camera, {300, 200}, 1.0, models::AhpPrior{}, 0);
  Landmark* other = init_ahp_landmark(*rig.map, *rig.camera, {500, 300}, 1.0, models::AhpPrior{}, 0);
  ASSERT_NE(ahp, nullptr);
  ASSERT_NE(other, nullptr);
  Landmark* euclidean = reparametrize_to_euclidean(*rig.map, *other);
  ASSERT_NE(euclidean, nullptr);
  filter::State& st = rig.map->state();
  const Eigen::Vector3d ahp_before = ahp->position(st.mean_vector());
  const Eigen::Vector3d euclidean_before = euclidean->position(st.mean_vector());
  const Eigen::Matrix3d euclidean_cov_before = st.cov(euclidean->block());
  const double rho_before = st.mean(ahp->block())[6];
  const double first_rescale_at = drive_stretched(rig, 1.25, 3.0);
  // Windows close at an image's prediction, from the posterior of the previous image: the first from the start
  // (0.01 s) to 0.55 s (0.54 m), the next ones 0.5 m each. Each adds w |Δs|² = (1.25 L)² / (0.1² L + 0.3² L) to
  // the sum (8.4, then 7.8), and the standard error 1/sqrt(sum) is 0.34, 0.25, 0.204, then 0.18 < 0.2: the map is
  // rescaled at the prediction to the image after 2.05 s.
  EXPECT_GT(first_rescale_at, 2.0);
  EXPECT_LT(first_rescale_at, 2.2);
  EXPECT_EQ(rig.robot->rescales(), 1);
  EXPECT_NEAR(rig.robot->rescale_product(), 0.8, 1e-9);
  EXPECT_NEAR(rig.robot->pose().p.x(), first_rescale_at, 1e-9);  // 0.8 × 1.25 × the odometry's
  EXPECT_LT((ahp->position(st.mean_vector()) - 0.8 * ahp_before).norm(), 1e-9);
  EXPECT_NEAR(st.mean(ahp->block())[6], rho_before / 0.8, 1e-12);
  EXPECT_LT((euclidean->position(st.mean_vector()) - 0.8 * euclidean_before).norm(), 1e-9);
  EXPECT_LT((Eigen::Matrix3d(st.cov(euclidean->block())) - 0.64 * euclidean_cov_before).norm(),
            1e-9 * euclidean_cov_before.norm());
}

TEST(OdometryRobot, TheMapIsRescaledOnlyWhenAskedOnceTheOdometryKnowsTheScale) {
  {
    OdometryRig rig;  // OdometryScaleOptions{}: off
    start(rig);
    EXPECT_EQ(drive_stretched(rig, 1.25, 30.0), 0.0);
  }
  {
    // The defaults (max_se 0.05): this very noisy odometry (k_p 0.3 m/√m) knows the scale to 5 % after
    // 1 / 0.05² = 400 of the sum, 52 windows (26 m).
    OdometryRig rig(OdometryScaleOptions{.enabled = true});
    start(rig);
    const double at = drive_stretched(rig, 1.25, 30.0);
    EXPECT_GT(at, 26.0);
    EXPECT_LT(at, 26.2);
    EXPECT_NEAR(rig.robot->rescale_product(), 0.8, 1e-9);
  }
  {
    // With min_z 2, a path 1 % long is not rescaled: within two standard errors (0.09 after 30 m).
    OdometryRig rig(OdometryScaleOptions{.enabled = true, .max_se = 0.1, .min_z = 2.0});
    start(rig);
    EXPECT_EQ(drive_stretched(rig, 1.01, 30.0), 0.0);
  }
}

// Map::scale_lengths about a centre away from the origin, on a map that tracks the unobservable basis: means,
// covariance (P ← D P D with D = c on positions, 1/c on inverse distances) and basis (re-expressed at the new means)
// are checked against their closed forms, and every landmark is seen in the same direction as before.
TEST(Map, ScaleLengthsChangesMeansCovarianceAndBasisLikeTheClosedForm) {
  World world;
  filter::StateOptions so;
  so.nullspace_dim = Robot::kNullspaceDim;
  Map& map = world.add_map(so);
  auto r = std::make_unique<OdometryRobot>(models::OdometryParams{});
  Sensor& cam = r->add_sensor(std::make_unique<PinholeSensor>("cam0", support::vga_camera(), math::Pose{}));
  Eigen::VectorXd x0(7);
  x0 << 0.7, -0.4, 0.2, math::quat_to_wxyz(math::exp_so3(Eigen::Vector3d(0.1, -0.3, 0.2)));
  Robot& robot = map.add_robot(std::move(r), x0, 1e-3 * Eigen::MatrixXd::Identity(6, 6), 0);
  Landmark* ahp = init_ahp_landmark(map, cam, {300, 200}, 1.0, models::AhpPrior{}, 0);
  Landmark* other = init_ahp_landmark(map, cam, {500, 300}, 1.0, models::AhpPrior{}, 0);
  ASSERT_NE(ahp, nullptr);
  ASSERT_NE(other, nullptr);
  Landmark* euc = reparametrize_to_euclidean(map, *other);
  ASSERT_NE(euc, nullptr);
  filter::State& st = map.state();
  const std::vector<filter::BlockId> blocks = {robot.block(), ahp->block(), euc->block()};
  const auto dense_cov = [&] {
    Eigen::MatrixXd P(16, 16);
    for (int a = 0, ra = 0; a < 3; ra += st.block(blocks[a]).tangent_size(), ++a)
      for (int b = 0, rb = 0; b < 3; rb += st.block(blocks[b]).tangent_size(), ++b)
        P.block(ra, rb, st.block(blocks[a]).tangent_size(), st.block(blocks[b]).tangent_size()) =
            st.cov(blocks[a], blocks[b]);
    return P;
  };
  const Eigen::MatrixXd P0 = dense_cov();
  const Eigen::VectorXd x_robot = st.mean(robot.block()), x_ahp = st.mean(ahp->block()), x_euc = st.mean(euc->block());
  const auto direction = [&](const Landmark& l) {
    return l.to_sensor(st.mean_vector(), robot.pose(), nullptr, nullptr).normalized().eval();
  };
  const Eigen::Vector3d dir_ahp = direction(*ahp), dir_euc = direction(*euc);

  const double c = 0.8;
  const Eigen::Vector3d centre(0.3, -0.2, 0.1);
  ASSERT_TRUE(map.scale_lengths(c, centre));

  const auto moved = [&](const Eigen::Vector3d& p) { return (centre + c * (p - centre)).eval(); };
  EXPECT_LT((st.mean(robot.block()).head<3>() - moved(x_robot.head<3>())).norm(), 1e-15);
  EXPECT_EQ(st.mean(robot.block()).tail<4>(), x_robot.tail<4>());
  EXPECT_LT((st.mean(ahp->block()).head<3>() - moved(x_ahp.head<3>())).norm(), 1e-15);
  EXPECT_EQ(st.mean(ahp->block()).segment<3>(3), x_ahp.segment<3>(3));
  EXPECT_NEAR(st.mean(ahp->block())[6], x_ahp[6] / c, 1e-15);
  EXPECT_LT((st.mean(euc->block()) - moved(x_euc)).norm(), 1e-15);
  Eigen::VectorXd d(16);
  d << c, c, c, 1, 1, 1, c, c, c, 1, 1, 1, 1 / c, c, c, c;
  const Eigen::MatrixXd P_expected = d.asDiagonal() * P0 * d.asDiagonal();
  EXPECT_LT((dense_cov() - P_expected).norm(), 1e-15 * P_expected.norm());
  EXPECT_LT((direction(*ahp) - dir_ahp).norm(), 1e-12);
  EXPECT_LT((direction(*euc) - dir_euc).norm(), 1e-12);

  // The basis at the new means: the robot's own, and [I −[p]×] for positions, [0 −[m]×] for AHP's direction.
  Eigen::MatrixXd N_robot(6, 6);
  robot.nullspace(st.mean(robot.block()), N_robot);
  EXPECT_LT((Eigen::MatrixXd(st.nullspace(robot.block())) - N_robot).norm(), 1e-12);
  Eigen::MatrixXd N_ahp = Eigen::MatrixXd::Zero(7, 6);
  N_ahp.block<3, 3>(0, 0).setIdentity();
  N_ahp.block<3, 3>(0, 3) = -math::skew(st.mean(ahp->block()).head<3>());
  N_ahp.block<3, 3>(3, 3) = -math::skew(st.mean(ahp->block()).segment<3>(3));
  EXPECT_LT((Eigen::MatrixXd(st.nullspace(ahp->block())) - N_ahp).norm(), 1e-12);
  Eigen::MatrixXd N_euc(3, 6);
  N_euc << Eigen::Matrix3d::Identity(), -math::skew(st.mean(euc->block()));
  EXPECT_LT((Eigen::MatrixXd(st.nullspace(euc->block())) - N_euc).norm(), 1e-12);
}

TEST(Map, ScaleLengthsRefusesAStateWithBlocksItCannotRescale) {
  OdometryRig rig;
  rig.odometry(10 * kNsPerMs, 0.01, 0.0);
  rig.image(10 * kNsPerMs);
  ASSERT_TRUE(rig.map->scale_lengths(2.0));
  rig.odometry(20 * kNsPerMs, 0.01, 0.0);
  rig.image(20 * kNsPerMs);
  const double x = rig.robot->pose().p.x();
  EXPECT_NEAR(x, 0.01, 1e-15);
  // A block of a sensor (metric extrinsics, say) that the map does not know how to rescale: nothing changes.
  const Eigen::Vector3d extrinsics(0.1, 0.0, 0.0);
  ASSERT_TRUE(rig.map->state()
                  .add_block(filter::BlockLayout::euclidean(3), extrinsics, Eigen::Matrix3d::Identity())
                  .has_value());
  EXPECT_FALSE(rig.map->scale_lengths(2.0));
  EXPECT_EQ(rig.robot->pose().p.x(), x);
  EXPECT_THROW(rig.map->scale_lengths(0.0), InvariantError);
}

}  // namespace
}  // namespace rtslam::slam
