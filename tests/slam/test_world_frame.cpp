// slam::change_world_frame (slam/world_frame.hpp): a map with an inertial robot (estimated camera extrinsics), an
// AHP and a Euclidean landmark moved by a known rotation and translation:
//  - the means move as x_G = R x_W + t (robot position, attitude q_GW q, velocity and gravity turned, biases and
//    extrinsics unchanged; landmark points), so every landmark seen from the robot is where it was;
//  - the covariance becomes J P Jᵀ with J = diag(R, I, R, I, I, R | I | R, R, 1 | R) built here by hand, plus the
//    change's own uncertainty as a common motion: the landmarks in the robot's frame keep their covariance exactly,
//    the robot's absolute position gains Σ_c;
//  - with the observability-constrained filter the tracked basis is that of the new estimates: the robot's rows are
//    Robot::nullspace at its new mean, and the camera Jacobians at the moved state annihilate it.
#include <gtest/gtest.h>

#include "rtslam/math/rotation.hpp"
#include "rtslam/models/landmarks/ahp.hpp"
#include "rtslam/slam/landmark_init.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/observation.hpp"
#include "rtslam/slam/odometry_robot.hpp"
#include "rtslam/slam/world_frame.hpp"
#include "support/test_camera.hpp"

namespace rtslam::slam {
namespace {

using Eigen::Matrix3d;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;
using I = models::InertialIndex;

models::CameraIntrinsics frame_camera() {
  return support::euroc_camera();
}

struct TestMap {
  World world;
  Map* map = nullptr;
  Sensor* cam = nullptr;
  Robot* robot = nullptr;
  Landmark* ahp = nullptr;
  Landmark* euc = nullptr;
  explicit TestMap(int nullspace_dim = Robot::kNullspaceDim) {
    filter::StateOptions so;
    so.nullspace_dim = nullspace_dim;
    map = &world.add_map(so);
    auto r = std::make_unique<InertialRobot>(models::InertialParams{});
    cam = &r->add_sensor(std::make_unique<PinholeSensor>(
        "cam", frame_camera(), math::Pose{math::exp_so3(Vector3d(0.1, -0.2, 0.05)), Vector3d(0.05, -0.02, 0.01)}));
    cam->estimate_extrinsics(1e-4 * Eigen::Matrix<double, 6, 6>::Identity());
    models::Vector19d x;
    x << 0.4, -1.2, 1.1,
        math::quat_to_wxyz(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Vector3d(1, -2, 3).normalized()))), 0.8, -0.3,
        0.2, 0.03, -0.02, 0.05, 0.002, -0.004, 0.001, 0.3, -0.2, -9.79;
    MatrixXd P = 1e-3 * MatrixXd::Identity(18, 18);
    P(0, 4) = P(4, 0) = 2e-4;  // some correlation inside the robot block
    P(6, 15) = P(15, 6) = -1e-4;
    robot = &map->add_robot(std::move(r), x, P, 0);
    ahp = init_ahp_landmark(*map, *cam, {300, 200}, 1.0, models::AhpPrior{}, 0);
    Landmark* other = init_ahp_landmark(*map, *cam, {500, 300}, 1.0, models::AhpPrior{}, 0);
    euc = reparametrize_to_euclidean(*map, *other);
  }
  Vector3d point(const Landmark& l) const {
    const auto x = map->state().mean(l.block());
    if (l.type() == LandmarkType::AhpPoint) return models::ahp_to_euclidean(x.head<7>());
    return x.head<3>();
  }
  // The landmark in the robot's frame R_WRᵀ (x − p) and its Jacobian over [robot | landmark] tangents.
  Vector3d in_robot(const Landmark& l, MatrixXd* J = nullptr) const {
    const filter::State& s = map->state();
    const auto xr = s.mean(robot->block());
    const Matrix3d R_WR = math::quat_from_wxyz(xr.segment<4>(I::kQ)).toRotationMatrix();
    const Vector3d d = point(l) - xr.head<3>();
    if (J) {
      const int nl = s.block(l.block()).tangent_size();
      J->setZero(3, 18 + nl);
      J->leftCols<3>() = -R_WR.transpose();
      J->block<3, 3>(0, 3) = math::skew(R_WR.transpose() * d);
      Eigen::Matrix<double, 3, 7> J_p_L;
      if (l.type() == LandmarkType::AhpPoint) {
        models::ahp_to_euclidean(s.mean(l.block()).head<7>(), &J_p_L);
        J->rightCols(nl) = R_WR.transpose() * J_p_L.leftCols(nl);  // AHP tangent = ambient (no manifold part)
      } else {
        J->rightCols(3) = R_WR.transpose();
      }
    }
    return R_WR.transpose() * d;
  }
  MatrixXd joint_cov(const Landmark& l) const {
    const filter::State& s = map->state();
    const filter::BlockId a = robot->block(), b = l.block();
    const int nl = s.block(b).tangent_size();
    MatrixXd P(18 + nl, 18 + nl);
    P << MatrixXd(s.cov(a, a)), MatrixXd(s.cov(a, b)), MatrixXd(s.cov(b, a)), MatrixXd(s.cov(b, b));
    return P;
  }
};

WorldChange known_change() {
  WorldChange c;
  c.T_GW = math::Pose{math::exp_so3(Vector3d(0.2, -0.1, 0.9)), Vector3d(3.0, -1.5, 0.7)};
  c.center_G = Vector3d(2.5, -1.0, 1.0);
  return c;
}

MatrixXd block_jacobian(const TestMap& m, filter::BlockId id, const Matrix3d& R) {
  const int n = m.map->state().block(id).tangent_size();
  MatrixXd J = MatrixXd::Identity(n, n);
  if (id == m.robot->block()) {
    J.block<3, 3>(I::kDp, I::kDp) = R;
    J.block<3, 3>(I::kDv, I::kDv) = R;
    J.block<3, 3>(I::kDg, I::kDg) = R;
  } else if (id == m.ahp->block()) {
    J.block<3, 3>(0, 0) = R;
    J.block<3, 3>(3, 3) = R;
  } else if (id == m.euc->block()) {
    J = R;
  }
  return J;
}

TEST(WorldFrame, MoveTransformsMeansAndCovarianceAndKeepsTheRelativeGeometry) {
  TestMap m;
  ASSERT_NE(m.ahp, nullptr);
  ASSERT_NE(m.euc, nullptr);
  filter::State& s = m.map->state();
  const std::vector<filter::BlockId> ids = {m.robot->block(), m.cam->block(), m.ahp->block(), m.euc->block()};
  const VectorXd xr0 = s.mean(m.robot->block()), xs0 = s.mean(m.cam->block());
  const Vector3d ahp0 = m.point(*m.ahp), euc0 = m.point(*m.euc);
  const Vector3d ahp_R0 = m.in_robot(*m.ahp), euc_R0 = m.in_robot(*m.euc);
  std::vector<std::vector<MatrixXd>> P0(ids.size(), std::vector<MatrixXd>(ids.size()));
  for (std::size_t i = 0; i < ids.size(); ++i)
    for (std::size_t j = 0; j < ids.size(); ++j) P0[i][j] = s.cov(ids[i], ids[j]);
  const WorldChange c = known_change();
  const Matrix3d R = c.T_GW.q.toRotationMatrix();
  ASSERT_EQ(change_world_frame(*m.map, c), "");

  const auto xr = s.mean(m.robot->block());
  EXPECT_LT((xr.head<3>() - (R * xr0.head<3>() + c.T_GW.p)).norm(), 1e-12);
  EXPECT_LT(math::log_so3(math::quat_from_wxyz(xr.segment<4>(I::kQ)).conjugate() *
                          (c.T_GW.q * math::quat_from_wxyz(xr0.segment<4>(I::kQ))))
                .norm(), 1e-12);
  EXPECT_LT((xr.segment<3>(I::kV) - R * xr0.segment<3>(I::kV)).norm(), 1e-12);
  EXPECT_LT((xr.segment<3>(I::kG) - R * xr0.segment<3>(I::kG)).norm(), 1e-12);
  EXPECT_EQ(VectorXd(xr.segment<6>(I::kAb)), VectorXd(xr0.segment<6>(I::kAb)));  // biases, in R
  EXPECT_EQ(VectorXd(s.mean(m.cam->block())), xs0);                             // extrinsics, in R
  EXPECT_LT((m.point(*m.ahp) - (R * ahp0 + c.T_GW.p)).norm(), 1e-10);
  EXPECT_LT((m.point(*m.euc) - (R * euc0 + c.T_GW.p)).norm(), 1e-10);
  EXPECT_LT((m.in_robot(*m.ahp) - ahp_R0).norm(), 1e-10);
  EXPECT_LT((m.in_robot(*m.euc) - euc_R0).norm(), 1e-10);
  for (std::size_t i = 0; i < ids.size(); ++i) {
    for (std::size_t j = 0; j < ids.size(); ++j) {
      const MatrixXd expected =
          block_jacobian(m, ids[i], R) * P0[i][j] * block_jacobian(m, ids[j], R).transpose();
      EXPECT_LT((MatrixXd(s.cov(ids[i], ids[j])) - expected).norm(), 1e-12 * (1.0 + expected.norm()))
          << "blocks " << i << ", " << j;
    }
  }
}

TEST(WorldFrame, TheChangesUncertaintyIsACommonMotion) {
  TestMap a, b;
  WorldChange c = known_change();
  ASSERT_EQ(change_world_frame(*a.map, c), "");
  c.cov.topLeftCorner<3, 3>() = Eigen::Vector3d(0.04, 0.09, 0.01).asDiagonal();
  c.cov.bottomRightCorner<3, 3>() = Eigen::Vector3d(1e-3, 2e-3, 0.03).asDiagonal();
  c.cov(0, 5) = c.cov(5, 0) = 1e-3;
  ASSERT_EQ(change_world_frame(*b.map, c), "");
  for (const auto& [la, lb] : {std::pair{a.ahp, b.ahp}, std::pair{a.euc, b.euc}}) {
    MatrixXd Ja, Jb;
    a.in_robot(*la, &Ja);
    b.in_robot(*lb, &Jb);
    const MatrixXd Pa = Ja * a.joint_cov(*la) * Ja.transpose(), Pb = Jb * b.joint_cov(*lb) * Jb.transpose();
    EXPECT_LT((Pa - Pb).norm(), 1e-9 * Pa.norm()) << to_string(la->type());
  }
  // The robot's position: Σ_c added; its attitude: R_GRᵀ Σ_φ R_GR.
  const filter::State &sa = a.map->state(), &sb = b.map->state();
  const MatrixXd dP = MatrixXd(sb.cov(b.robot->block())) - MatrixXd(sa.cov(a.robot->block()));
  const Matrix3d R_GR = math::quat_from_wxyz(sb.mean(b.robot->block()).segment<4>(I::kQ)).toRotationMatrix();
  const Vector3d p = sb.mean(b.robot->block()).head<3>();
  const Eigen::Matrix<double, 3, 6> Gp = (Eigen::Matrix<double, 3, 6>() << Matrix3d::Identity(),
                                          -math::skew(p - c.center_G)).finished();
  EXPECT_LT((dP.block<3, 3>(I::kDp, I::kDp) - Gp * c.cov * Gp.transpose()).norm(), 1e-12);
  EXPECT_LT((dP.block<3, 3>(I::kDth, I::kDth) -
             R_GR.transpose() * c.cov.bottomRightCorner<3, 3>() * R_GR).norm(), 1e-12);
  // The extrinsics (in R) are untouched by it.
  EXPECT_LT((MatrixXd(sb.cov(b.cam->block())) - MatrixXd(sa.cov(a.cam->block()))).norm(), 1e-15);
}

TEST(WorldFrame, TheTrackedBasisIsThatOfTheMovedEstimates) {
  // Two maps built and moved identically: one tracks the basis, the other (no constraint) gives the exact Jacobians.
  TestMap m, plain(0);
  ASSERT_EQ(change_world_frame(*m.map, known_change()), "");
  ASSERT_EQ(change_world_frame(*plain.map, known_change()), "");
  const filter::State& s = m.map->state();
  const filter::State& sp = plain.map->state();
  ASSERT_EQ(s.mean_vector(), sp.mean_vector());
  MatrixXd N_r(18, Robot::kNullspaceDim);
  m.robot->nullspace(s.mean(m.robot->block()), N_r);
  EXPECT_LT((MatrixXd(s.nullspace(m.robot->block())) - N_r).norm(), 1e-12);
  // The exact camera Jacobians at the moved state annihilate the tracked basis.
  for (const auto& [l, lp] : {std::pair{m.ahp, plain.ahp}, std::pair{m.euc, plain.euc}}) {
    Observation o = *lp->observation_of(*plain.cam);
    ASSERT_TRUE(predict_observation(sp, sp.mean_vector(), o, 0.0, true));
    MatrixXd N(18 + 6 + s.block(l->block()).tangent_size(), Robot::kNullspaceDim);
    N << MatrixXd(s.nullspace(m.robot->block())), MatrixXd(s.nullspace(m.cam->block())),
        MatrixXd(s.nullspace(l->block()));
    ASSERT_EQ(o.H.cols(), N.rows());
    EXPECT_LT((MatrixXd(o.H) * N).norm(), 1e-9 * MatrixXd(o.H).norm()) << to_string(l->type());
  }
}

// The odometry robot [p q] (no vectors in W): its pose moves like the others', J = diag(R, I), and a landmark seen
// from it stays where it was in its frame.
TEST(WorldFrame, MovesAnOdometryRobot) {
  World world;
  Map& map = world.add_map(filter::StateOptions{});
  auto r = std::make_unique<OdometryRobot>(models::OdometryParams{});
  Sensor& cam = r->add_sensor(std::make_unique<PinholeSensor>("cam", frame_camera(), math::Pose{}));
  VectorXd x(7);
  x << 0.4, -1.2, 1.1,
      math::quat_to_wxyz(Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Vector3d(1, -2, 3).normalized())));
  MatrixXd P = 1e-3 * MatrixXd::Identity(6, 6);
  P(0, 4) = P(4, 0) = 2e-4;
  Robot& robot = map.add_robot(std::move(r), x, P, 0);
  Landmark* l = init_ahp_landmark(map, cam, {300, 200}, 1.0, models::AhpPrior{}, 0);
  ASSERT_NE(l, nullptr);
  filter::State& s = map.state();
  auto in_robot = [&] {
    const auto xr = s.mean(robot.block());
    const Matrix3d R_WR = math::quat_from_wxyz(xr.segment<4>(3)).toRotationMatrix();
    return Vector3d(R_WR.transpose() * (models::ahp_to_euclidean(s.mean(l->block()).head<7>()) - xr.head<3>()));
  };
  const Vector3d l_R0 = in_robot();
  const MatrixXd P0 = s.cov(robot.block());
  const WorldChange c = known_change();
  const Matrix3d R = c.T_GW.q.toRotationMatrix();
  ASSERT_EQ(change_world_frame(map, c), "");
  const auto xr = s.mean(robot.block());
  EXPECT_LT((xr.head<3>() - (R * x.head<3>() + c.T_GW.p)).norm(), 1e-12);
  EXPECT_LT(math::log_so3(math::quat_from_wxyz(xr.segment<4>(3)).conjugate() *
                          (c.T_GW.q * math::quat_from_wxyz(x.segment<4>(3))))
                .norm(), 1e-12);
  EXPECT_LT((in_robot() - l_R0).norm(), 1e-10);
  MatrixXd J = MatrixXd::Identity(6, 6);
  J.topLeftCorner<3, 3>() = R;
  EXPECT_LT((MatrixXd(s.cov(robot.block())) - J * P0 * J.transpose()).norm(), 1e-12);
}

}  // namespace
}  // namespace rtslam::slam
