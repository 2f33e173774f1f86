// The batched correction shared by the point data managers (slam/batch_correction.hpp):
//  - one iteration is the EKF: the same mean and covariance as filter::State::correct with the stacked H, z − h
//    and σ² I;
//  - the iterated EKF converges to the Gauss-Newton MAP point: at its last linearization point x* the correction
//    satisfies x* ⊖ x₀ = K(z − h(x*) + H (x* ⊖ x₀)), i.e. (I − KH)(x* ⊖ x₀) = K (z − h(x*)), i.e. (as
//    K = (I − KH) P₀ Hᵀ R⁻¹) x* ⊖ x₀ = P₀ Hᵀ R⁻¹ (z − h(x*)) — the stationarity of the MAP cost, written without
//    inverting P₀ (singular here: the anchors of new landmarks are the camera's position) — and with a strongly
//    non-linear start (young inverse-depth landmarks far from their prior) its residual is smaller than the EKF's.
#include <gtest/gtest.h>

#include "rtslam/slam/batch_correction.hpp"
#include "rtslam/slam/landmark_init.hpp"
#include "rtslam/slam/map.hpp"
#include "support/test_camera.hpp"

namespace rtslam::slam {
namespace {

// A constant-velocity robot with one camera, four AHP landmarks initialized at 2 m (prior) while they are at
// 1–1.4 m, then the robot translates sideways by 0.2 m: their measurements are far from the prediction.
struct Scene {
  World world;
  Map& map = world.add_map();
  Sensor* sensor = nullptr;
  std::vector<Eigen::Vector3d> points = {{-0.3, 0.2, 1.0}, {0.25, -0.15, 1.2}, {0.1, 0.3, 1.4}, {-0.2, -0.25, 1.1}};
  std::vector<Observation*> obs;
  Scene() {
    auto robot = std::make_unique<ConstantVelocityRobot>(models::ConstantVelocityParams{});
    sensor = &robot->add_sensor(std::make_unique<PinholeSensor>("cam", support::vga_camera(), math::Pose::identity()));
    Eigen::VectorXd x = Eigen::VectorXd::Zero(13);
    x[3] = 1.0;
    Eigen::MatrixXd P = Eigen::MatrixXd::Zero(12, 12);
    P.bottomRightCorner<6, 6>() = 0.04 * Eigen::MatrixXd::Identity(6, 6);
    Robot& r = map.add_robot(std::move(robot), x, P, 0);
    const models::PinholeCamera cam(support::vga_camera());
    for (const auto& p : points) {
      Eigen::Vector2d z;
      EXPECT_TRUE(cam.project(p, z));
      models::AhpPrior prior;
      prior.d_min = 1.0;
      EXPECT_NE(init_ahp_landmark(map, *sensor, z, 0.5, prior, 0), nullptr);
    }
    // The robot moves (CV prediction with a 0.2 m/s x-velocity over 1 s), and the camera sees the points from there.
    map.state().mean(r.block())[7] = 0.2;
    EXPECT_TRUE(r.predict_to(from_seconds(1.0)));
    const Eigen::Vector3d p_true(0.2, 0.0, 0.0);
    for (std::size_t k = 0; k < points.size(); ++k) {
      Observation* o = map.landmarks()[k]->observation_of(*sensor);
      EXPECT_TRUE(cam.project(points[k] - p_true, o->z));
      obs.push_back(o);
    }
  }
};

TEST(BatchCorrector, OneIterationIsTheStackedEkfUpdate) {
  Scene a, b;
  BatchCorrector corrector(8);
  BatchCorrectionOptions o;
  o.sigma_px = 0.5;
  ASSERT_TRUE(corrector.correct(a.map.state(), a.obs, o).ok());
  EXPECT_EQ(corrector.used(), 4);
  // By hand on the twin scene.
  filter::State& st = b.map.state();
  std::vector<filter::BlockId> blocks = {b.map.robots()[0]->block()};
  int cols = 12;
  for (Observation* ob : b.obs) {
    ASSERT_TRUE(predict_observation(st, st.mean_vector(), *ob, 0.0, true));
    blocks.push_back(ob->landmark_block());
    cols += 7;
  }
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(8, cols);
  Eigen::VectorXd y(8);
  for (int k = 0; k < 4; ++k) {
    H.block(2 * k, 0, 2, 12) = b.obs[static_cast<std::size_t>(k)]->H.leftCols(12);
    H.block(2 * k, 12 + 7 * k, 2, 7) = b.obs[static_cast<std::size_t>(k)]->H.rightCols(7);
    y.segment<2>(2 * k) = b.obs[static_cast<std::size_t>(k)]->z - b.obs[static_cast<std::size_t>(k)]->h;
  }
  ASSERT_TRUE(st.correct(blocks, H, y, 0.25 * Eigen::MatrixXd::Identity(8, 8)).ok());
  EXPECT_EQ(a.map.state().mean_vector(), b.map.state().mean_vector());
  EXPECT_EQ(a.map.state().covariance(), b.map.state().covariance());
}

TEST(BatchCorrector, CurrentJacobiansGiveTheSameCorrectionAsPredictingAgain) {
  // The active search's contract (jacobians_current): the observations were predicted with their Jacobians at the
  // current mean, then a RANSAC hypothesis left its own h in them (a prediction at another mean, no Jacobians).
  Scene a, b;
  Eigen::VectorXd elsewhere = b.map.state().mean_vector();
  elsewhere.head<3>() += Eigen::Vector3d(0.05, -0.02, 0.01);
  for (Observation* ob : b.obs) {
    ASSERT_TRUE(predict_observation(b.map.state(), b.map.state().mean_vector(), *ob, 0.0, true));
    predict_observation(b.map.state(), elsewhere, *ob, 0.0, false);
  }
  BatchCorrector corrector(8);
  BatchCorrectionOptions o;
  o.sigma_px = 0.5;
  ASSERT_TRUE(corrector.correct(a.map.state(), a.obs, o).ok());
  o.jacobians_current = true;
  ASSERT_TRUE(corrector.correct(b.map.state(), b.obs, o).ok());
  EXPECT_EQ(a.map.state().mean_vector(), b.map.state().mean_vector());
  EXPECT_EQ(a.map.state().covariance(), b.map.state().covariance());
}

TEST(BatchCorrector, IteratedUpdateReachesTheMapPointAndFitsBetterThanTheEkf) {
  Scene ekf, iekf;
  const Eigen::VectorXd x0 = iekf.map.state().mean_vector();
  const Eigen::MatrixXd P0 = iekf.map.state().covariance();
  BatchCorrector corrector(8);
  BatchCorrectionOptions o;
  o.sigma_px = 0.5;
  ASSERT_TRUE(corrector.correct(ekf.map.state(), ekf.obs, o).ok());
  o.iterations = 20;
  o.iteration_tolerance = 1e-10;
  ASSERT_TRUE(corrector.correct(iekf.map.state(), iekf.obs, o).ok());
  // Residuals after each update (predicted at the new means).
  auto residual = [](Scene& s) {
    double r2 = 0.0;
    for (Observation* ob : s.obs) {
      EXPECT_TRUE(predict_observation(s.map.state(), s.map.state().mean_vector(), *ob, 0.0, true));
      r2 += (ob->z - ob->h).squaredNorm();
    }
    return std::sqrt(r2 / static_cast<double>(s.obs.size()));
  };
  const double r_ekf = residual(ekf), r_iekf = residual(iekf);
  std::printf("RMS pixel residual after the update: EKF %.4f px, iterated %.4f px\n", r_ekf, r_iekf);
  EXPECT_LT(r_iekf, r_ekf);
  // MAP optimality at x*: x* ⊖ x0 = P0 Hᵀ R⁻¹ (z − h(x*)) over the involved blocks (here every block).
  const filter::State& st = iekf.map.state();
  std::vector<filter::BlockId> blocks = {iekf.map.robots()[0]->block()};
  for (Observation* ob : iekf.obs) blocks.push_back(ob->landmark_block());
  const int n = 12 + 7 * 4;
  Eigen::VectorXd dx(n), g = Eigen::VectorXd::Zero(n);
  Eigen::MatrixXd P(n, n);
  int c = 0;
  std::vector<int> offs;
  for (filter::BlockId b : blocks) offs.push_back(st.block(b).tangent_offset);
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const auto& bi = st.block(blocks[i]);
    // x* ⊖ x0 per block: Euclidean parts subtract, the quaternion by boxminus.
    const Eigen::VectorXd xa = st.mean_vector().segment(bi.ambient_offset, bi.ambient_size());
    const Eigen::VectorXd xb = x0.segment(bi.ambient_offset, bi.ambient_size());
    if (i == 0) {
      dx.segment<3>(c) = xa.head<3>() - xb.head<3>();
      dx.segment<3>(c + 3) = math::boxminus(math::quat_from_wxyz(xa.segment<4>(3)), math::quat_from_wxyz(xb.segment<4>(3)));
      dx.segment<6>(c + 6) = xa.tail<6>() - xb.tail<6>();
    } else {
      dx.segment(c, 7) = xa - xb;
    }
    int cj = 0;
    for (std::size_t j = 0; j < blocks.size(); ++j) {
      const auto& bj = st.block(blocks[j]);
      P.block(c, cj, bi.tangent_size(), bj.tangent_size()) =
          P0.block(bi.tangent_offset, bj.tangent_offset, bi.tangent_size(), bj.tangent_size());
      cj += bj.tangent_size();
    }
    c += bi.tangent_size();
  }
  for (std::size_t k = 0; k < iekf.obs.size(); ++k) {
    Observation* ob = iekf.obs[k];
    ASSERT_TRUE(predict_observation(st, st.mean_vector(), *ob, 0.0, true));
    const Eigen::Vector2d r = (ob->z - ob->h) / 0.25;
    g.head<12>() += ob->H.leftCols(12).transpose() * r;
    g.segment<7>(12 + 7 * static_cast<int>(k)) += ob->H.rightCols(7).transpose() * r;
  }
  const Eigen::VectorXd rhs = P * g;
  EXPECT_GT(dx.norm(), 0.01);
  EXPECT_LT((dx - rhs).norm(), 1e-6 * dx.norm()) << "dx " << dx.transpose() << "\nP H' R^-1 r " << rhs.transpose();
}

}  // namespace
}  // namespace rtslam::slam

namespace rtslam::slam {
namespace {

// First-estimate Jacobians (slam/consistency: fej). Propagation: a robot predicted to t1, corrected, then predicted
// to t2 has the covariance of the same robot predicted from its first estimate at t1 (its prediction, not the
// corrected mean), while its mean starts from the corrected one.
TEST(FirstEstimateJacobians, RobotTransitionUsesThePredictionBeforeTheCorrections) {
  auto make = [](bool fej) {
    auto world = std::make_unique<World>();
    Map& map = world->add_map();
    auto robot = std::make_unique<ConstantVelocityRobot>(models::ConstantVelocityParams{});
    robot->set_first_estimate_jacobians(fej);
    Eigen::VectorXd x = Eigen::VectorXd::Zero(13);
    x[3] = 1.0;
    x.segment<3>(7) << 0.3, -0.1, 0.2;
    x.segment<3>(10) << 0.5, 0.2, -0.4;
    map.add_robot(std::move(robot), x, 0.01 * Eigen::MatrixXd::Identity(12, 12), 0);
    return world;
  };
  auto fej = make(true), plain = make(false), reference = make(false);
  auto robot_of = [](World& w) -> Robot& { return *w.maps().front()->robots().front(); };
  for (World* w : {fej.get(), plain.get(), reference.get()}) ASSERT_TRUE(robot_of(*w).predict_to(from_seconds(0.1)));
  // A correction moves the mean of the first two (attitude and angular rate).
  for (World* w : {fej.get(), plain.get()}) {
    auto x = w->maps().front()->state().mean(robot_of(*w).block());
    x.segment<4>(3) = math::quat_to_wxyz(math::boxplus(math::quat_from_wxyz(x.segment<4>(3)), Eigen::Vector3d(0.2, -0.1, 0.3)));
    x.segment<3>(10) += Eigen::Vector3d(0.3, 0.1, -0.2);
  }
  for (World* w : {fej.get(), plain.get(), reference.get()}) ASSERT_TRUE(robot_of(*w).predict_to(from_seconds(0.2)));
  const auto P = [&](World& w) { return Eigen::MatrixXd(w.maps().front()->state().cov(robot_of(w).block())); };
  EXPECT_LT((P(*fej) - P(*reference)).norm(), 1e-15);
  EXPECT_GT((P(*plain) - P(*reference)).norm(), 1e-6);
  EXPECT_EQ(fej->maps().front()->state().mean(robot_of(*fej).block()),
            plain->maps().front()->state().mean(robot_of(*plain).block()));
}

// Measurement: with a linearization mean, h is the prediction at the current mean and H the Jacobian at the
// linearization mean.
TEST(FirstEstimateJacobians, ObservationPredictsAtTheMeanAndLinearizesAtTheFirstEstimate) {
  Scene s;
  filter::State& st = s.map.state();
  Eigen::VectorXd lin = st.mean_vector();
  const auto& rb = st.block(s.map.robots()[0]->block());
  lin.segment<3>(rb.ambient_offset) += Eigen::Vector3d(0.05, -0.02, 0.01);
  Observation& o = *s.obs[0];
  Observation at_mean = o, at_lin = o;
  ASSERT_TRUE(predict_observation(st, st.mean_vector(), at_mean, 0.0, true));
  ASSERT_TRUE(predict_observation(st, lin, at_lin, 0.0, true));
  ASSERT_TRUE(predict_observation(st, st.mean_vector(), o, 0.0, true, &lin));
  EXPECT_EQ(o.h, at_mean.h);
  EXPECT_EQ(Eigen::MatrixXd(o.H), Eigen::MatrixXd(at_lin.H));
  EXPECT_GT((Eigen::MatrixXd(o.H) - Eigen::MatrixXd(at_mean.H)).norm(), 1e-6);
}

}  // namespace
}  // namespace rtslam::slam
