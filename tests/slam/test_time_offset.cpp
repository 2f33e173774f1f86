// The camera–IMU time offset as a state of the sensor (Sensor::estimate_time_offset; Li & Mourikis 2014, OpenVINS):
//  - the observation's Jacobian over [robot, extrinsics, δt_d, landmark] against numeric differentiation of h;
//  - its δt_d column is the landmark's pixel velocity: the derivative of h when the inertial robot is predicted
//    (from its IMU samples) to a later datum time, so the model matches what a real clock offset does;
//  - the robot's pose rate [v; ω_m − b_g] is the time derivative of the integrated pose;
//  - with observability constraints the δt_d block has zero basis rows and the constrained H still annihilates it;
//  - the System predicts the robot to the datum's stamp plus the current estimate.
#include <gtest/gtest.h>

#include "rtslam/slam/landmark_init.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/observation.hpp"
#include "rtslam/slam/sensor.hpp"
#include "support/jacobian_check.hpp"
#include "support/test_camera.hpp"

namespace rtslam::slam {
namespace {

using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

models::CameraIntrinsics offset_camera() {
  return support::euroc_camera_radtan();
}

// A moving, turning robot with biases and gravity off the axes.
VectorXd offset_inertial_state() {
  VectorXd x = VectorXd::Zero(19);
  x.head<3>() << 0.3, -0.2, 1.1;
  x.segment<4>(3) = math::quat_to_wxyz(math::exp_so3(Vector3d(0.2, -0.4, 0.3)));
  x.segment<3>(7) << 0.8, -0.5, 0.3;
  x.segment<3>(10) << 0.02, -0.03, 0.05;
  x.segment<3>(13) << 0.01, -0.02, 0.015;
  x.segment<3>(16) << 0.1, -0.05, -9.8;
  return x;
}

// IMU reading k (200 Hz): rotating at ~1 rad/s about a turning axis, accelerating.
models::ImuMeasurement reading(int k) {
  const double t = 0.005 * k;
  models::ImuMeasurement m;
  m.gyro << 0.9 + 0.3 * std::sin(3 * t), -0.6 + 0.2 * t, 0.4 * std::cos(2 * t);
  m.accel << 0.5 + std::sin(4 * t), 9.6 - 0.3 * t, 0.8 * std::cos(3 * t);
  return m;
}

constexpr TimeNs kImuPeriod = 5'000'000;

struct OffsetScene {
  World world;
  Map* map = nullptr;
  InertialRobot* robot = nullptr;
  Sensor* sensor = nullptr;
  std::vector<Landmark*> landmarks;
  // An inertial robot at t = 0 with IMU samples over [0, 0.1] s, a camera with estimated extrinsics and time offset,
  // an AHP landmark and a Euclidean one.
  // With constant_rate, the gyro reads reading(0)'s rate throughout (the mean rate of pose_rate is the reading).
  explicit OffsetScene(int nullspace_dim = 0, bool extrinsics = true, bool constant_rate = false) {
    filter::StateOptions so;
    so.nullspace_dim = nullspace_dim;
    map = &world.add_map(so);
    auto owned = std::make_unique<InertialRobot>(models::InertialParams{});
    robot = owned.get();
    sensor = &owned->add_sensor(std::make_unique<PinholeSensor>(
        "cam", offset_camera(), math::Pose{math::exp_so3(Vector3d(0.1, -0.2, 0.05)), Vector3d(0.05, -0.02, 0.01)}));
    if (extrinsics) sensor->estimate_extrinsics(1e-4 * Eigen::Matrix<double, 6, 6>::Identity());
    sensor->estimate_time_offset(25e-6, 0.05);
    for (int k = 0; k <= 20; ++k) {
      models::ImuMeasurement m = reading(k);
      if (constant_rate) m.gyro = reading(0).gyro;
      owned->add_imu(k * kImuPeriod, m);
    }
    map->add_robot(std::move(owned), offset_inertial_state(), 1e-3 * MatrixXd::Identity(18, 18), 0);
  }
  void add_landmarks() {
    Landmark* ahp = init_ahp_landmark(*map, *sensor, {300, 200}, 1.0, models::AhpPrior{}, 0);
    Landmark* other = init_ahp_landmark(*map, *sensor, {500, 300}, 1.0, models::AhpPrior{}, 0);
    ASSERT_NE(ahp, nullptr);
    ASSERT_NE(other, nullptr);
    landmarks = {ahp, reparametrize_to_euclidean(*map, *other)};
    map->state().mean(ahp->block())[6] *= 0.7;  // off the initialization point
  }
};

TEST(TimeOffset, TheBlockStartsAtZeroWithItsPriorAndZeroBasisRows) {
  OffsetScene s(Robot::kNullspaceDim);
  const filter::State& st = s.map->state();
  ASSERT_NE(s.sensor->time_block(), filter::kNoBlock);
  EXPECT_EQ(st.block(s.sensor->time_block()).tangent_size(), 1);
  EXPECT_EQ(s.sensor->time_offset(st.mean_vector()), 0.0);
  EXPECT_DOUBLE_EQ(st.cov(s.sensor->time_block())(0, 0), 25e-6);
  EXPECT_EQ(MatrixXd(st.nullspace(s.sensor->time_block())), MatrixXd::Zero(1, Robot::kNullspaceDim));
}

TEST(TimeOffset, ShiftIsTheEstimateClampedToItsRange) {
  OffsetScene s;
  filter::State& st = s.map->state();
  st.mean(s.sensor->time_block())[0] = 0.0123;
  EXPECT_EQ(s.sensor->time_shift(st.mean_vector()), 12'300'000);
  st.mean(s.sensor->time_block())[0] = -0.2;
  EXPECT_EQ(s.sensor->time_shift(st.mean_vector()), -50'000'000);
}

TEST(TimeOffset, PoseRateIsTheVelocityAndTheMeanRateOfTheLastPrediction) {
  // After predict_to(t0), predict_to(t1) (t1 − t0 >= 10 ms): ω is the rotation increment over [t0, t1] divided by its length, v the derivative of the position at t1.
  OffsetScene s;
  Eigen::Matrix<double, 6, 1> xi;
  const TimeNs t0 = 12'000'000, t1 = 37'000'000, eps = 200'000;
  ASSERT_TRUE(s.robot->predict_to(t0));
  const math::Pose T0 = s.robot->pose();
  ASSERT_TRUE(s.robot->predict_to(t1));
  const math::Pose T1 = s.robot->pose();
  ASSERT_TRUE(s.robot->pose_rate(s.map->state().mean_vector(), xi));
  ASSERT_TRUE(s.robot->predict_to(t1 + eps));
  const math::Pose T2 = s.robot->pose();
  const Vector3d w_mean = math::log_so3(T0.q.conjugate() * T1.q) / to_seconds(t1 - t0);
  const Vector3d v_num = (T2.p - T1.p) / to_seconds(eps);
  EXPECT_LT((xi.tail<3>() - w_mean).norm(), 1e-3 * w_mean.norm()) << xi.tail<3>().transpose() << "\n" << w_mean.transpose();
  EXPECT_LT((xi.head<3>() - v_num).norm(), 2e-3 * v_num.norm()) << xi.head<3>().transpose() << "\n" << v_num.transpose();
}

// Every column of H at δt_d = the applied shift (where each frame is linearized: the System predicts the robot to
// the stamp plus the estimate), against central differences of h over every involved block.
TEST(TimeOffset, ObservationJacobianMatchesNumeric) {
  OffsetScene s;
  ASSERT_TRUE(s.robot->predict_to(43'000'000));
  s.add_landmarks();
  filter::State& st = s.map->state();
  st.mean(s.sensor->time_block())[0] = 0.003;
  s.sensor->set_applied_time_shift(3'000'000);
  st.mean(s.sensor->block()).head<3>() += Vector3d(0.01, -0.02, 0.005);
  for (Landmark* lm : s.landmarks) {
    Observation& o = *lm->observation_of(*s.sensor);
    ASSERT_TRUE(predict_observation(st, st.mean_vector(), o, 0.0, true));
    ASSERT_EQ(o.block_count, 4);
    EXPECT_EQ(o.blocks[2], s.sensor->time_block());
    const auto& rb = st.block(s.robot->block());
    const auto& sb = st.block(s.sensor->block());
    const auto& tb = st.block(s.sensor->time_block());
    const auto& lb = st.block(lm->block());
    const test::Layout in = test::Layout::euclidean(3)
                                .then_quaternion()
                                .then_euclidean(12)
                                .then_euclidean(3)
                                .then_quaternion()
                                .then_euclidean(1)
                                .then_euclidean(lb.ambient_size());
    VectorXd x0(19 + 7 + 1 + lb.ambient_size());
    x0 << st.mean(s.robot->block()), st.mean(s.sensor->block()), st.mean(s.sensor->time_block()), st.mean(lm->block());
    const auto f = [&](const VectorXd& x) {
      VectorXd mean = st.mean_vector();
      mean.segment(rb.ambient_offset, 19) = x.head(19);
      mean.segment(sb.ambient_offset, 7) = x.segment(19, 7);
      mean.segment(tb.ambient_offset, 1) = x.segment(26, 1);
      mean.segment(lb.ambient_offset, lb.ambient_size()) = x.tail(lb.ambient_size());
      Observation tmp = o;
      predict_observation(st, mean, tmp, 0.0, false);
      return VectorXd(tmp.h);
    };
    EXPECT_TRUE(test::check_jacobian(std::string("H with time offset, ") + to_string(lm->type()), f, x0, MatrixXd(o.H),
                                     in, test::Layout::euclidean(2), {.step = 1e-6, .rtol = 1e-5, .atol = 1e-4}));
    EXPECT_GT(std::abs(o.H(0, 18 + 6)) + std::abs(o.H(1, 18 + 6)), 10.0);  // px/s: the landmark moves in the image
  }
}

// The δt_d column is what a later capture time does: h predicted after integrating the IMU to t + ε, against h at
// t moved by H_td ε. Two identical scenes, one predicted further. The gyro rate is constant (the column uses the mean
// rate of the last prediction, the derivative the rate at t); the robot accelerates.
TEST(TimeOffset, TimeColumnIsThePixelVelocityUnderTheImuPrediction) {
  const TimeNs t = 61'000'000, eps = 100'000;
  for (int k = 0; k < 2; ++k) {
    OffsetScene a(0, false, true), b(0, false, true);
    ASSERT_TRUE(a.robot->predict_to(t - eps));
    ASSERT_TRUE(b.robot->predict_to(t - eps));
    a.add_landmarks();
    b.add_landmarks();
    OffsetScene c(0, false, true);  // the linearization at t
    ASSERT_TRUE(c.robot->predict_to(t - eps));
    c.add_landmarks();
    ASSERT_TRUE(c.robot->predict_to(t));
    ASSERT_TRUE(b.robot->predict_to(t + eps));
    Observation oa = *a.landmarks[static_cast<std::size_t>(k)]->observation_of(*a.sensor);
    Observation ob = *b.landmarks[static_cast<std::size_t>(k)]->observation_of(*b.sensor);
    Observation oc = *c.landmarks[static_cast<std::size_t>(k)]->observation_of(*c.sensor);
    ASSERT_TRUE(predict_observation(a.map->state(), a.map->state().mean_vector(), oa, 0.0, false));
    ASSERT_TRUE(predict_observation(b.map->state(), b.map->state().mean_vector(), ob, 0.0, false));
    ASSERT_TRUE(predict_observation(c.map->state(), c.map->state().mean_vector(), oc, 0.0, true));
    const Eigen::Vector2d numeric = (ob.h - oa.h) / to_seconds(2 * eps);
    const Eigen::Vector2d analytic = oc.H.col(18);  // [robot 18, δt_d, landmark]
    EXPECT_LT((numeric - analytic).norm(), 1e-4 * analytic.norm())
        << "numeric " << numeric.transpose() << " px/s, analytic " << analytic.transpose();
  }
}

TEST(TimeOffset, ConstrainedJacobianAnnihilatesTheBasisWithTheTimeBlock) {
  OffsetScene s(Robot::kNullspaceDim);
  ASSERT_TRUE(s.robot->predict_to(43'000'000));
  s.add_landmarks();
  filter::State& st = s.map->state();
  st.mean(s.robot->block()).head<3>() += Vector3d(0.05, -0.03, 0.02);
  for (Landmark* lm : s.landmarks) {
    Observation o = *lm->observation_of(*s.sensor);
    ASSERT_TRUE(predict_observation(st, st.mean_vector(), o, 0.0, true));
    const int tl = st.block(lm->block()).tangent_size();
    MatrixXd N(18 + 6 + 1 + tl, Robot::kNullspaceDim);
    N << MatrixXd(st.nullspace(s.robot->block())), MatrixXd(st.nullspace(s.sensor->block())),
        MatrixXd(st.nullspace(s.sensor->time_block())), MatrixXd(st.nullspace(lm->block()));
    EXPECT_LT((MatrixXd(o.H) * N).norm(), 1e-10 * MatrixXd(o.H).norm());
    EXPECT_GT(o.H.col(24).norm(), 1.0);  // the time column survives the projection
  }
}

}  // namespace
}  // namespace rtslam::slam
