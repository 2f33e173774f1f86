#include <gtest/gtest.h>

#include "rtslam/core/random.hpp"
#include "rtslam/slam/landmark_init.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/observation.hpp"
#include "support/jacobian_check.hpp"
#include "support/test_camera.hpp"

namespace rtslam::slam {
namespace {

models::CameraIntrinsics test_camera() {
  models::CameraIntrinsics c = support::vga_camera();
  c.model = models::DistortionModel::RadTan;
  c.coeffs = {-0.2, 0.05, 1e-4, -2e-4};
  return c;
}

Eigen::VectorXd cv_mean(const Eigen::Vector3d& p, const Eigen::Quaterniond& q) {
  Eigen::VectorXd x = Eigen::VectorXd::Zero(13);
  x.head<3>() = p;
  x.segment<4>(3) = math::quat_to_wxyz(q);
  x.segment<3>(7) << 0.1, 0.0, 0.0;
  return x;
}

// Two robots, each with two cameras looking forward (z) with different mounts.
struct TwoByTwo {
  World world;
  Map* map = nullptr;
  std::vector<Sensor*> sensors;
  TwoByTwo() {
    map = &world.add_map();
    for (int r = 0; r < 2; ++r) {
      auto robot = std::make_unique<ConstantVelocityRobot>(models::ConstantVelocityParams{}, "robot" + std::to_string(r));
      robot->add_sensor(std::make_unique<PinholeSensor>("left", test_camera(),
                                                        math::Pose{Eigen::Quaterniond::Identity(), {-0.1, 0, 0}}));
      robot->add_sensor(std::make_unique<PinholeSensor>(
          "right", test_camera(), math::Pose{math::exp_so3(Eigen::Vector3d(0, 0.05, 0)), {0.1, 0, 0}}));
      Eigen::MatrixXd P = 1e-4 * Eigen::MatrixXd::Identity(12, 12);
      if (r == 0) P.topLeftCorner<6, 6>().setZero();  // gauge: the first robot's pose defines W
      map->add_robot(std::move(robot), cv_mean({0.3 * r, 0, 0}, Eigen::Quaterniond::Identity()), P, 0);
    }
    sensors = map->sensors();
  }
};

TEST(ObjectModel, TwoRobotsTwoCamerasShareLandmarks) {
  TwoByTwo w;
  Map& map = *w.map;
  ASSERT_EQ(w.sensors.size(), 4u);
  for (size_t i = 0; i < 4; ++i) EXPECT_EQ(w.sensors[i]->id(), static_cast<int>(i));
  // Both robots move (robot 0's pose gains uncertainty), then landmarks are initialized from its left camera.
  for (const auto& r : map.robots()) ASSERT_TRUE(r->predict_to(from_seconds(0.05)));
  const std::vector<Eigen::Vector2d> pixels = {{300, 200}, {350, 260}, {280, 300}, {400, 180}, {200, 240}};
  for (const auto& px : pixels) {
    ASSERT_NE(init_ahp_landmark(map, *w.sensors[0], px, 1.0, models::AhpPrior{}, 0), nullptr);
  }
  ASSERT_EQ(map.landmarks().size(), pixels.size());
  for (const auto& l : map.landmarks()) {
    ASSERT_EQ(l->observations().size(), 4u) << "one observation per sensor of every robot";
    for (size_t i = 0; i < 4; ++i) EXPECT_EQ(l->observations()[i].sensor, w.sensors[i]);
  }
  // The initial landmark is correlated with robot 0 only.
  const Landmark& l0 = *map.landmarks()[0];
  EXPECT_GT(map.state().cov(l0.block(), map.robots()[0]->block()).norm(), 0.0);
  EXPECT_EQ(map.state().cov(l0.block(), map.robots()[1]->block()).norm(), 0.0);

  // Both robots move; every sensor predicts every observation; robot 1's cameras correct with what they see.
  for (const auto& r : map.robots()) ASSERT_TRUE(r->predict_to(from_seconds(0.1)));
  int corrected = 0;
  for (Sensor* s : {w.sensors[2], w.sensors[3]}) {
    for (const auto& l : map.landmarks()) {
      Observation& o = *l->observation_of(*s);
      if (!predict_observation(map.state(), map.state().mean_vector(), o, 0.0, true)) continue;
      compute_innovation_covariance(map.state(), o, 1.0);
      EXPECT_GT(o.S.determinant(), 0.0);
      const Eigen::Vector2d y(0.5, -0.5);
      const auto res = map.state().correct(o.involved(), o.H, y, o.R, 9.0);
      EXPECT_TRUE(res.ok()) << filter::to_string(res.status);
      ++corrected;
    }
  }
  EXPECT_GT(corrected, 4);
  // Shared landmarks now correlate the two robots.
  EXPECT_GT(map.state().cov(map.robots()[0]->block(), map.robots()[1]->block()).norm(), 0.0);
}

TEST(ObjectModel, ReparametrizationKeepsIdentityAndObservationsAndFreesRows) {
  TwoByTwo w;
  Map& map = *w.map;
  Landmark* l = init_ahp_landmark(map, *w.sensors[1], {330, 250}, 1.0, models::AhpPrior{}, 3);
  ASSERT_NE(l, nullptr);
  l->observations()[2].counters.matched = 7;
  const int id = l->id();
  const int used = map.state().tangent_used();
  const Eigen::Vector3d p_before = l->position(map.state().mean_vector());
  Landmark* e = reparametrize_to_euclidean(map, *l);
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(e->type(), LandmarkType::EuclideanPoint);
  EXPECT_EQ(e->id(), id);
  EXPECT_EQ(e->frame_created, 3);
  EXPECT_EQ(e->observations().size(), 4u);
  EXPECT_EQ(e->observations()[2].counters.matched, 7);
  EXPECT_EQ(e->observations()[2].landmark, e);
  EXPECT_EQ(map.state().tangent_used(), used - 4);
  EXPECT_LT((e->position(map.state().mean_vector()) - p_before).norm(), 1e-12);
  map.remove_landmark(*e);
  EXPECT_EQ(map.state().tangent_used(), used - 7);
  EXPECT_TRUE(map.landmarks().empty());
}

// The chained observation Jacobian (camera ∘ landmark ∘ sensor pose ∘ robot pose) against numeric differences
// over the robot block [p q v ω] and the landmark block, for AHP and Euclidean landmarks.
TEST(ObjectModel, ObservationJacobianMatchesNumeric) {
  TwoByTwo w;
  Map& map = *w.map;
  Landmark* ahp = init_ahp_landmark(map, *w.sensors[0], {310, 230}, 1.0, models::AhpPrior{}, 0);
  Landmark* other = init_ahp_landmark(map, *w.sensors[0], {360, 200}, 1.0, models::AhpPrior{}, 0);
  ASSERT_NE(ahp, nullptr);
  ASSERT_NE(other, nullptr);
  Landmark* euc = reparametrize_to_euclidean(map, *other);
  const filter::State& st = map.state();
  Sensor* s = w.sensors[3];  // robot 1, right camera: a non-trivial mount, and a robot not the anchor's
  for (Landmark* l : {ahp, euc}) {
    Observation& o = *l->observation_of(*s);
    ASSERT_TRUE(predict_observation(st, st.mean_vector(), o, 0.0, true));
    const auto& rb = st.block(s->robot().block());
    const auto& lb = st.block(l->block());
    test::Layout in = test::Layout::euclidean(3).then_quaternion().then_euclidean(6).then_euclidean(lb.ambient_size());
    Eigen::VectorXd x0(13 + lb.ambient_size());
    x0 << st.mean(s->robot().block()), st.mean(l->block());
    const auto f = [&](const Eigen::VectorXd& x) {
      Eigen::VectorXd mean = st.mean_vector();
      mean.segment(rb.ambient_offset, 13) = x.head(13);
      mean.segment(lb.ambient_offset, lb.ambient_size()) = x.tail(lb.ambient_size());
      Observation tmp = o;
      predict_observation(st, mean, tmp, 0.0, false);
      return Eigen::VectorXd(tmp.h);
    };
    EXPECT_TRUE(test::check_jacobian(std::string("H ") + to_string(l->type()), f, x0, Eigen::MatrixXd(o.H), in,
                                     test::Layout::euclidean(2), {.step = 1e-6, .rtol = 1e-5, .atol = 1e-4}));
  }
}

}  // namespace
}  // namespace rtslam::slam

namespace rtslam::slam {
namespace {

// A camera whose extrinsics are a map block: the observation Jacobian has [robot, sensor, landmark] columns, each
// checked against numeric differentiation; a landmark initialized from it is correlated with the extrinsics.
using Eigen::MatrixXd;

TEST(ObjectModel, EstimatedExtrinsicsJoinTheObservationJacobian) {
  World world;
  Map& map = world.add_map();
  auto robot = std::make_unique<ConstantVelocityRobot>(models::ConstantVelocityParams{});
  Sensor& cam = robot->add_sensor(std::make_unique<PinholeSensor>(
      "cam", test_camera(), math::Pose{math::exp_so3(Eigen::Vector3d(0.02, -0.05, 0.1)), {0.05, -0.02, 0.01}}));
  Eigen::Matrix<double, 6, 6> prior = Eigen::Matrix<double, 6, 6>::Identity() * 1e-4;
  cam.estimate_extrinsics(prior);
  Eigen::MatrixXd P = 1e-4 * Eigen::MatrixXd::Identity(12, 12);
  P.topLeftCorner<6, 6>().setZero();
  map.add_robot(std::move(robot), cv_mean({0.1, 0.2, 0.0}, math::exp_so3(Eigen::Vector3d(0.1, 0.2, -0.1))), P, 0);
  ASSERT_NE(cam.block(), filter::kNoBlock);
  const filter::State& st = map.state();
  EXPECT_EQ(MatrixXd(st.cov(cam.block())), MatrixXd(prior));
  Landmark* l = init_ahp_landmark(map, cam, {300, 220}, 1.0, models::AhpPrior{}, 0);
  ASSERT_NE(l, nullptr);
  EXPECT_GT(MatrixXd(st.cov(l->block(), cam.block())).norm(), 1e-6);  // the anchor depends on T_RS
  Landmark* euc = reparametrize_to_euclidean(map, *init_ahp_landmark(map, cam, {420, 300}, 1.0, models::AhpPrior{}, 0));
  // Move the estimates off the initialization point so that every column is exercised.
  map.state().mean(cam.block()).head<3>() += Eigen::Vector3d(0.01, -0.02, 0.005);
  map.state().mean(l->block())[6] *= 0.7;
  for (Landmark* lm : {l, euc}) {
    Observation& o = *lm->observation_of(cam);
    ASSERT_TRUE(predict_observation(st, st.mean_vector(), o, 0.0, true));
    ASSERT_EQ(o.block_count, 3);
    EXPECT_EQ(o.blocks[1], cam.block());
    const auto& rb = st.block(cam.robot().block());
    const auto& sb = st.block(cam.block());
    const auto& lb = st.block(lm->block());
    const test::Layout in = test::Layout::euclidean(3)
                                .then_quaternion()
                                .then_euclidean(6)
                                .then_euclidean(3)
                                .then_quaternion()
                                .then_euclidean(lb.ambient_size());
    Eigen::VectorXd x0(13 + 7 + lb.ambient_size());
    x0 << st.mean(cam.robot().block()), st.mean(cam.block()), st.mean(lm->block());
    const auto f = [&](const Eigen::VectorXd& x) {
      Eigen::VectorXd mean = st.mean_vector();
      mean.segment(rb.ambient_offset, 13) = x.head(13);
      mean.segment(sb.ambient_offset, 7) = x.segment(13, 7);
      mean.segment(lb.ambient_offset, lb.ambient_size()) = x.tail(lb.ambient_size());
      Observation tmp = o;
      predict_observation(st, mean, tmp, 0.0, false);
      return Eigen::VectorXd(tmp.h);
    };
    EXPECT_TRUE(test::check_jacobian(std::string("H with extrinsics, ") + to_string(lm->type()), f, x0,
                                     Eigen::MatrixXd(o.H), in, test::Layout::euclidean(2),
                                     {.step = 1e-6, .rtol = 1e-5, .atol = 1e-4}));
  }
}

// The second-order noise term of an inverse-depth landmark, ½ (d²z/dρ²)(d²z/dρ²)ᵀ σ_ρ⁴, against a numeric second
// difference of the prediction along ρ: exact for an undistorted pinhole; with radial-tangential distortion the
// formula neglects the distortion's own curvature (here within 15 %).
TEST(ObjectModel, InverseDepthSecondOrderTermMatchesNumericSecondDerivative) {
  for (const bool distorted : {false, true}) {
    World world;
    Map& map = world.add_map();
    auto robot = std::make_unique<ConstantVelocityRobot>(models::ConstantVelocityParams{});
    models::CameraIntrinsics cam = test_camera();
    if (!distorted) {
      cam.model = models::DistortionModel::None;
      cam.coeffs.clear();
    }
    Sensor& s = robot->add_sensor(std::make_unique<PinholeSensor>("cam", cam, math::Pose{}));
    Eigen::MatrixXd P = 1e-4 * Eigen::MatrixXd::Identity(12, 12);
    P.topLeftCorner<6, 6>().setZero();
    map.add_robot(std::move(robot), cv_mean({0, 0, 0}, Eigen::Quaterniond::Identity()), P, 0);
    Landmark* l = init_ahp_landmark(map, s, {420, 180}, 1.0, models::AhpPrior{}, 0);
    ASSERT_NE(l, nullptr);
    filter::State& st = map.state();
    // The camera moves away from the anchor (sideways and forward) so that the projection is curved along ρ.
    st.mean(s.robot().block()).head<3>() << 0.3, -0.1, 0.25;
    Observation o = *l->observation_of(s);
    ASSERT_TRUE(predict_observation(st, st.mean_vector(), o, 0.0, true));
    const double var_rho = st.cov(l->block())(6, 6);
    const int i_rho = st.block(l->block()).ambient_offset + 6;
    const double d = 1e-3;
    Eigen::Vector2d z[3];
    for (int k = 0; k < 3; ++k) {
      Eigen::VectorXd mean = st.mean_vector();
      mean[i_rho] += (k - 1) * d;
      Observation tmp = o;
      predict_observation(st, mean, tmp, 0.0, false);
      z[k] = tmp.h;
    }
    const Eigen::Vector2d d2z = (z[2] - 2.0 * z[1] + z[0]) / (d * d);
    const Eigen::Matrix2d expected = 0.5 * var_rho * var_rho * d2z * d2z.transpose();
    ASSERT_GT(expected.norm(), 1e-3) << "the set-up must make the term visible";
    EXPECT_LT((o.R_depth - expected).norm(), (distorted ? 0.15 : 1e-4) * expected.norm())
        << (distorted ? "radtan" : "pinhole") << "\nformula:\n" << o.R_depth << "\nnumeric:\n" << expected;
  }
}

}  // namespace
}  // namespace rtslam::slam
