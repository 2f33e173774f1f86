// The robots' unobservable bases (Robot::nullspace) are what the observability-constrained filter relies on: a
// global translation t and rotation φ of the world. They must be exact invariant directions of the models:
//  - prediction: F(x) N(x) = N(f(x)) for the exact transition Jacobian (inertial, several IMU steps; constant
//    velocity), i.e. moving the world and then predicting equals predicting and then moving the world;
//  - measurement: with landmark rows inherited at initialization (N_L = J_init N_R), every observation Jacobian
//    at the initialization point satisfies H N = 0 already (AHP and Euclidean after reparametrization), so the
//    projection only removes what linearization at later estimates adds;
//  - with `nullspace_dim` on, the map's Jacobians satisfy H N = 0 at any later estimate too.
#include <gtest/gtest.h>

#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/landmark_init.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/observation.hpp"
#include "support/test_camera.hpp"

namespace rtslam::slam {
namespace {

using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;
using models::InertialIndex;

models::Vector19d inertial_state() {
  models::Vector19d x;
  x << 0.4, -1.2, 1.1, math::quat_to_wxyz(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Vector3d(1, -2, 3).normalized()))),
      0.8, -0.3, 0.2, 0.03, -0.02, 0.05, 0.002, -0.004, 0.001, 0.3, -0.2, -9.79;
  return x;
}

models::ImuMeasurement imu_at(double t) {
  models::ImuMeasurement m;
  m.gyro << 1.5 * std::sin(3.0 * t), -0.8 + 0.4 * t, 2.0 * std::cos(2.0 * t);
  m.accel << 3.0 * std::cos(4.0 * t), 1.2, 9.81 + 2.0 * std::sin(t);
  return m;
}

TEST(Observability, InertialPredictionMapsTheBasisOntoTheBasisAtThePredictedState) {
  InertialRobot robot(models::InertialParams{});
  models::Vector19d x = inertial_state();
  MatrixXd N0(18, 6), N1(18, 6);
  robot.nullspace(x, N0);
  MatrixXd Phi = MatrixXd::Identity(18, 18);
  models::Matrix18d F;
  for (int k = 0; k < 8; ++k) {  // eight 5 ms steps with fast rotation and large specific force
    models::inertial_predict(x, imu_at(0.005 * k), imu_at(0.005 * (k + 1)), 0.005, models::InertialParams{}, x, &F);
    Phi = F * Phi;
  }
  robot.nullspace(x, N1);
  EXPECT_LT((Phi * N0 - N1).norm(), 1e-9 * N1.norm());
  // The basis has full rank (a rotation of the world moves the attitude, not only positions).
  EXPECT_EQ(Eigen::FullPivLU<MatrixXd>(N0).rank(), 6);
}

TEST(Observability, ConstantVelocityPredictionMapsTheBasisOntoTheBasisAtThePredictedState) {
  ConstantVelocityRobot robot(models::ConstantVelocityParams{});
  models::Vector13d x;
  x << 0.4, -1.2, 1.1, math::quat_to_wxyz(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Vector3d(1, -2, 3).normalized()))),
      0.8, -0.3, 0.2, 1.1, -0.7, 0.4;
  MatrixXd N0(12, 6), N1(12, 6);
  robot.nullspace(x, N0);
  models::Vector13d x1;
  models::Matrix12d F;
  models::constant_velocity_predict(x, 0.05, models::ConstantVelocityParams{}, x1, &F, nullptr);
  robot.nullspace(x1, N1);
  EXPECT_LT((F * N0 - N1).norm(), 1e-12 * N1.norm());
}

models::CameraIntrinsics camera() {
  return support::euroc_camera_radtan();
}

struct InertialMap {
  World world;
  Map* map = nullptr;
  Sensor* sensor = nullptr;
  explicit InertialMap(int nullspace_dim) {
    filter::StateOptions so;
    so.nullspace_dim = nullspace_dim;
    map = &world.add_map(so);
    auto robot = std::make_unique<InertialRobot>(models::InertialParams{});
    sensor = &robot->add_sensor(std::make_unique<PinholeSensor>(
        "cam", camera(), math::Pose{math::exp_so3(Vector3d(0.1, -0.2, 0.05)), Vector3d(0.05, -0.02, 0.01)}));
    map->add_robot(std::move(robot), inertial_state(), 1e-3 * MatrixXd::Identity(18, 18), 0);
  }
};

TEST(Observability, InheritedLandmarkRowsMakeTheExactJacobianAnnihilateTheBasis) {
  // Two maps built identically: one tracks the basis, the other gives the exact (unprojected) Jacobians.
  InertialMap w(Robot::kNullspaceDim), plain(0);
  std::vector<Landmark*> tracked, exact;
  for (InertialMap* m : {&w, &plain}) {
    Landmark* ahp = init_ahp_landmark(*m->map, *m->sensor, {300, 200}, 1.0, models::AhpPrior{}, 0);
    Landmark* other = init_ahp_landmark(*m->map, *m->sensor, {500, 300}, 1.0, models::AhpPrior{}, 0);
    ASSERT_NE(ahp, nullptr);
    ASSERT_NE(other, nullptr);
    Landmark* euc = reparametrize_to_euclidean(*m->map, *other);
    (m == &w ? tracked : exact) = {ahp, euc};
  }
  const filter::State& st = w.map->state();
  const filter::State& sp = plain.map->state();
  ASSERT_EQ(st.mean_vector(), sp.mean_vector());
  for (std::size_t k = 0; k < 2; ++k) {
    Observation o = *exact[k]->observation_of(*plain.sensor);
    ASSERT_TRUE(predict_observation(sp, sp.mean_vector(), o, 0.0, true));
    MatrixXd N(18 + st.block(tracked[k]->block()).tangent_size(), 6);
    N << MatrixXd(st.nullspace(w.sensor->robot().block())), MatrixXd(st.nullspace(tracked[k]->block()));
    EXPECT_LT((MatrixXd(o.H) * N).norm(), 1e-9 * MatrixXd(o.H).norm()) << to_string(exact[k]->type());
  }
}

TEST(Observability, ConstrainedJacobiansAnnihilateTheBasisAtLaterEstimates) {
  InertialMap w(Robot::kNullspaceDim);
  Map& map = *w.map;
  Landmark* l = init_ahp_landmark(map, *w.sensor, {380, 260}, 1.0, models::AhpPrior{}, 0);
  ASSERT_NE(l, nullptr);
  filter::State& st = map.state();
  // Move the estimates (as corrections would): the exact Jacobian no longer annihilates the stored basis, the
  // constrained one does.
  st.mean(l->block()).tail<1>()[0] *= 0.6;
  st.mean(w.sensor->robot().block()).head<3>() += Vector3d(0.05, -0.03, 0.02);
  Observation o = *l->observation_of(*w.sensor);
  ASSERT_TRUE(predict_observation(st, st.mean_vector(), o, 0.0, true));
  MatrixXd N(25, 6);
  N << MatrixXd(st.nullspace(w.sensor->robot().block())), MatrixXd(st.nullspace(l->block()));
  EXPECT_LT((MatrixXd(o.H) * N).norm(), 1e-10 * MatrixXd(o.H).norm());
  InertialMap plain(0);
  Landmark* lp = init_ahp_landmark(*plain.map, *plain.sensor, {380, 260}, 1.0, models::AhpPrior{}, 0);
  plain.map->state().mean(lp->block()).tail<1>()[0] *= 0.6;
  plain.map->state().mean(plain.sensor->robot().block()).head<3>() += Vector3d(0.05, -0.03, 0.02);
  Observation op = *lp->observation_of(*plain.sensor);
  ASSERT_TRUE(predict_observation(plain.map->state(), plain.map->state().mean_vector(), op, 0.0, true));
  EXPECT_GT((MatrixXd(op.H) * N).norm(), 1e-4 * MatrixXd(op.H).norm());
}

// The constraint must not change what a camera can measure: the constrained H has no velocity, bias or gravity
// columns, and with estimated extrinsics a change of the robot pose compensated by the extrinsics (T_WS unchanged)
// is still invisible.
TEST(Observability, ConstrainedJacobiansKeepTheMeasurementStructure) {
  World world;
  filter::StateOptions so;
  so.nullspace_dim = Robot::kNullspaceDim;
  Map& map = world.add_map(so);
  auto robot = std::make_unique<InertialRobot>(models::InertialParams{});
  Sensor& cam = robot->add_sensor(std::make_unique<PinholeSensor>(
      "cam", camera(), math::Pose{math::exp_so3(Vector3d(0.1, -0.2, 0.05)), Vector3d(0.05, -0.02, 0.01)}));
  cam.estimate_extrinsics(1e-4 * Eigen::Matrix<double, 6, 6>::Identity());
  map.add_robot(std::move(robot), inertial_state(), 1e-3 * MatrixXd::Identity(18, 18), 0);
  Landmark* l = init_ahp_landmark(map, cam, {380, 260}, 1.0, models::AhpPrior{}, 0);
  ASSERT_NE(l, nullptr);
  filter::State& st = map.state();
  st.mean(l->block()).tail<1>()[0] *= 0.6;
  st.mean(cam.robot().block()).head<3>() += Vector3d(0.05, -0.03, 0.02);
  Observation o = *l->observation_of(cam);
  ASSERT_TRUE(predict_observation(st, st.mean_vector(), o, 0.0, true));
  ASSERT_EQ(o.H.cols(), 18 + 6 + 7);
  EXPECT_EQ(MatrixXd(o.H.middleCols(6, 12)), MatrixXd::Zero(2, 12));  // v, a_b, ω_b, g
  // Robot pose moved by δ_R, extrinsics by δ_S = −J_TWS_TRS⁻¹ J_TWS_TWR δ_R: T_WS is unchanged to first order.
  Eigen::Matrix<double, 6, 6> J_R, J_S;
  cam.pose_in_world(st.mean_vector(), &J_R, &J_S);
  Eigen::Matrix<double, 6, 1> d_R;
  d_R << 0.3, -0.1, 0.2, 0.05, 0.02, -0.04;
  const Eigen::Matrix<double, 6, 1> d_S = -J_S.inverse() * J_R * d_R;
  EXPECT_LT((MatrixXd(o.H.leftCols(6)) * d_R + MatrixXd(o.H.middleCols(18, 6)) * d_S).norm(), 1e-9 * MatrixXd(o.H).norm());
  MatrixXd N(31, 6);
  N << MatrixXd(st.nullspace(cam.robot().block())), MatrixXd(st.nullspace(cam.block())), MatrixXd(st.nullspace(l->block()));
  EXPECT_LT((MatrixXd(o.H) * N).norm(), 1e-10 * MatrixXd(o.H).norm());
}

}  // namespace
}  // namespace rtslam::slam
