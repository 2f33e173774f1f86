// The inertial robot of the map: buffered IMU samples integrated to an image time in one covariance update equal
// the per-sample chain of midpoint steps (mean, robot covariance and cross-covariances with a landmark), the
// reading at an image time between two samples is interpolated, and time and coverage errors are reported.
#include <gtest/gtest.h>

#include <cmath>

#include "rtslam/core/error.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/robot.hpp"

namespace rtslam::slam {
namespace {

using models::InertialIndex;

models::ImuMeasurement reading(double t) {
  models::ImuMeasurement m;
  m.gyro << 0.3 * std::sin(2.0 * t), -0.2 + 0.1 * t, 0.5 * std::cos(t);
  m.accel << 0.4 * std::cos(3.0 * t), 0.2, 9.81 + 0.3 * std::sin(t);
  return m;
}

models::Vector19d start_state() {
  models::Vector19d x = models::Vector19d::Zero();
  x.segment<3>(InertialIndex::kP) << 0.1, -0.2, 1.0;
  x.segment<4>(InertialIndex::kQ) = math::quat_to_wxyz(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized())));
  x.segment<3>(InertialIndex::kV) << 0.5, 0.1, -0.2;
  x.segment<3>(InertialIndex::kAb) << 0.02, -0.01, 0.03;
  x.segment<3>(InertialIndex::kWb) << 0.001, 0.002, -0.003;
  x.segment<3>(InertialIndex::kG) << 0.0, 0.0, -9.81;
  return x;
}

Eigen::MatrixXd start_cov() {
  Eigen::MatrixXd A = Eigen::MatrixXd::Random(18, 18) * 0.01;
  Eigen::MatrixXd P = A * A.transpose() + 1e-4 * Eigen::MatrixXd::Identity(18, 18);
  P.topLeftCorner(6, 18).setZero();
  P.topLeftCorner(18, 6).setZero();
  return P;
}

TEST(InertialRobot, BufferedIntegrationEqualsThePerSampleChain) {
  World world;
  filter::StateOptions so;
  so.tangent_capacity = 40;
  Map& map = world.add_map(so);
  models::InertialParams params;
  auto owned = std::make_unique<InertialRobot>(params);
  InertialRobot& robot = *owned;
  const TimeNs dt = 5'000'000;  // 200 Hz
  map.add_robot(std::move(owned), start_state(), start_cov(), 0);
  // A landmark-like block correlated with the robot, to check the cross-covariances.
  Eigen::MatrixXd Pl = 0.04 * Eigen::MatrixXd::Identity(3, 3);
  const auto lmk = map.state().add_block(filter::BlockLayout::euclidean(3), Eigen::Vector3d(1, 2, 3), Pl);
  ASSERT_TRUE(lmk);
  map.state().cov(*lmk, robot.block()).col(7).setConstant(0.001);
  map.state().cov(robot.block(), *lmk).row(7).setConstant(0.001);

  for (int k = 0; k <= 12; ++k) robot.add_imu(k * dt, reading(k * 0.005));
  // Reference: chain the model's steps on copies of the mean and covariance.
  models::Vector19d x = start_state();
  Eigen::MatrixXd P = map.state().cov(robot.block());
  Eigen::MatrixXd C = map.state().cov(robot.block(), *lmk);
  models::Matrix18d F, Q;
  const TimeNs t_end = 10 * dt + 2'000'000;  // between samples 10 and 11
  for (int k = 0; k < 11; ++k) {
    const TimeNs t0 = k * dt, t1 = std::min<TimeNs>((k + 1) * dt, t_end);
    models::ImuMeasurement m1 = reading((k + 1) * 0.005);
    if (t1 < (k + 1) * dt) {
      const double s = static_cast<double>(t1 - t0) / static_cast<double>(dt);
      const models::ImuMeasurement a = reading(k * 0.005);
      m1.accel = a.accel + s * (m1.accel - a.accel);
      m1.gyro = a.gyro + s * (m1.gyro - a.gyro);
    }
    models::inertial_predict(x, reading(k * 0.005), m1, to_seconds(t1 - t0), params, x, &F, &Q);
    P = F * P * F.transpose() + Q;
    C = F * C;
    if (t1 == t_end) break;
  }
  ASSERT_TRUE(robot.predict_to(t_end));
  EXPECT_EQ(robot.time(), t_end);
  EXPECT_EQ(robot.samples_integrated(), 11);
  EXPECT_LT((map.state().mean(robot.block()) - x).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((map.state().cov(robot.block()) - P).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((map.state().cov(robot.block(), *lmk) - C).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_EQ(map.state().cov(*lmk), Pl);  // the landmark's own block is untouched

  // Continuing from the interpolated reading: the next interval starts at t_end with the same reading.
  const models::Vector19d x_mid = map.state().mean(robot.block());
  ASSERT_TRUE(robot.predict_to(11 * dt));
  const double s = 2.0 / 5.0;
  models::ImuMeasurement m_mid;
  m_mid.accel = reading(0.05).accel + s * (reading(0.055).accel - reading(0.05).accel);
  m_mid.gyro = reading(0.05).gyro + s * (reading(0.055).gyro - reading(0.05).gyro);
  models::Vector19d x_ref;
  models::inertial_predict(x_mid, m_mid, reading(0.055), to_seconds(11 * dt - t_end), params, x_ref);
  EXPECT_LT((map.state().mean(robot.block()) - x_ref).cwiseAbs().maxCoeff(), 1e-12);
}

// At rest (Robot::set_at_rest, the zero-velocity detector's verdict): the next prediction holds p, q, v and g and
// adds only the biases' random walk, for that prediction only; samples of the interval that show motion make it
// integrate as usual.
TEST(InertialRobot, AtRestTheNextPredictionHoldsTheStateUnlessTheSamplesMove) {
  World world;
  filter::StateOptions so;
  so.tangent_capacity = 40;
  Map& map = world.add_map(so);
  models::InertialParams params;
  auto owned = std::make_unique<InertialRobot>(params);
  InertialRobot& robot = *owned;
  const TimeNs dt = 5'000'000;
  models::Vector19d x0 = start_state();
  x0.segment<3>(InertialIndex::kV).setZero();
  map.add_robot(std::move(owned), x0, start_cov(), 0);
  // Readings of a vibrating body at rest: −g in the body frame plus the biases, and a wobble well under the bounds.
  const math::Pose T0{math::quat_from_wxyz(x0.segment<4>(InertialIndex::kQ)), x0.segment<3>(InertialIndex::kP)};
  const auto at_rest = [&](int k) {
    models::ImuMeasurement m;
    m.accel = T0.q.conjugate() * Eigen::Vector3d(0.0, 0.0, 9.81) + x0.segment<3>(InertialIndex::kAb) +
              Eigen::Vector3d(0.8, -0.5, 0.3) * std::sin(1.3 * k);
    m.gyro = x0.segment<3>(InertialIndex::kWb) + Eigen::Vector3d(0.02, 0.01, -0.03) * std::cos(0.7 * k);
    return m;
  };
  for (int k = 0; k <= 40; ++k) robot.add_imu(k * dt, at_rest(k));
  const Eigen::MatrixXd P0 = map.state().cov(robot.block());

  robot.set_at_rest(true);
  ASSERT_TRUE(robot.predict_to(10 * dt));
  EXPECT_EQ(robot.samples_held(), 10);
  EXPECT_EQ(robot.samples_integrated(), 0);
  EXPECT_EQ(map.state().mean(robot.block()), x0) << "held: the mean does not move";
  Eigen::MatrixXd dP = map.state().cov(robot.block()) - P0;
  const double ab = params.accelerometer_random_walk * params.accelerometer_random_walk * to_seconds(10 * dt);
  const double wb = params.gyroscope_random_walk * params.gyroscope_random_walk * to_seconds(10 * dt);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(dP(InertialIndex::kDab + i, InertialIndex::kDab + i), ab, 1e-15);
    EXPECT_NEAR(dP(InertialIndex::kDwb + i, InertialIndex::kDwb + i), wb, 1e-15);
    dP(InertialIndex::kDab + i, InertialIndex::kDab + i) = 0.0;
    dP(InertialIndex::kDwb + i, InertialIndex::kDwb + i) = 0.0;
  }
  EXPECT_LT(dP.cwiseAbs().maxCoeff(), 1e-15) << "only the biases' variances grow";

  // The verdict is for one prediction: the next one integrates (and moves the mean, the readings being noisy).
  ASSERT_TRUE(robot.predict_to(20 * dt));
  EXPECT_EQ(robot.samples_held(), 10);
  EXPECT_EQ(robot.samples_integrated(), 10);
  EXPECT_NE(map.state().mean(robot.block()), x0);

  // At rest said, but a sample of the interval turns at 1 rad/s: integrated, not held.
  for (int k = 41; k <= 60; ++k) {
    models::ImuMeasurement m = at_rest(k);
    if (k == 45) m.gyro.z() += 1.0;
    robot.add_imu(k * dt, m);
  }
  robot.set_at_rest(true);
  ASSERT_TRUE(robot.predict_to(50 * dt));
  EXPECT_EQ(robot.samples_held(), 10);
  EXPECT_EQ(robot.samples_integrated(), 40);
}

TEST(InertialRobot, CoverageAndOrderErrorsAreReported) {
  World world;
  Map& map = world.add_map({});
  auto owned = std::make_unique<InertialRobot>(models::InertialParams{});
  InertialRobot& robot = *owned;
  map.add_robot(std::move(owned), start_state(), start_cov(), 0);
  EXPECT_FALSE(robot.imu_coverage().has_value());
  EXPECT_THROW(robot.predict_to(1000), DataError);  // no IMU at all
  robot.add_imu(0, reading(0));
  robot.add_imu(5'000'000, reading(0.005));
  EXPECT_EQ(*robot.imu_coverage(), 5'000'000);
  EXPECT_THROW(robot.add_imu(5'000'000, reading(0.005)), DataError);  // not after the previous one
  models::ImuMeasurement bad = reading(0.01);
  bad.gyro.x() = std::nan("");
  EXPECT_THROW(robot.add_imu(10'000'000, bad), DataError);
  EXPECT_THROW(robot.predict_to(6'000'000), DataError);  // beyond the last sample
  EXPECT_TRUE(robot.predict_to(5'000'000));
  EXPECT_FALSE(robot.predict_to(1'000'000));  // backwards
}

}  // namespace
}  // namespace rtslam::slam
