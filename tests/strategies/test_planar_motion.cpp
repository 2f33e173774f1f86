// The planar-motion pseudo-measurement (strategies/planar_motion.hpp): its Jacobian against numerical
// differentiation, one update against the closed-form Kalman result, and its options.
#include <cmath>
#include <memory>
#include <string>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "support/jacobian_check.hpp"

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/absolute_sensor.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/robot.hpp"
#include "rtslam/slam/sensor.hpp"
#include "rtslam/strategies/planar_motion.hpp"
#include "support/test_camera.hpp"

namespace rtslam::strategies {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

TEST(PlanarMotion, JacobianMatchesNumericalDifferentiation) {
  Rng rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  const auto gauss3 = [&] { return Vector3d(g(rng), g(rng), g(rng)); };
  const test::Layout pose = test::Layout::euclidean(3).then_quaternion();  // [p, q wxyz], tangent [δp δθ]
  test::JacobianCheckOptions tight;
  tight.rtol = 1e-8;
  tight.atol = 1e-8;
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::VectorXd x0(7);
    x0 << gauss3(), math::quat_to_wxyz(math::exp_so3(gauss3()));
    const Vector3d up = gauss3().normalized();
    // The x axis as the normal too (the plane basis's other branch).
    const Vector3d n = trial % 5 == 0 ? Vector3d::UnitX() : Vector3d(gauss3().normalized());
    const Vector3d p0 = gauss3();
    const auto h_of = [&](const Eigen::VectorXd& x) -> Eigen::VectorXd {
      Vector3d h;
      Eigen::Matrix<double, 3, 6> unused;
      planar_motion_measurement(x.head<3>(), math::quat_from_wxyz(x.tail<4>()).toRotationMatrix(), up, n, p0, h,
                                unused);
      return h;
    };
    Vector3d h;
    Eigen::Matrix<double, 3, 6> H;
    planar_motion_measurement(x0.head<3>(), math::quat_from_wxyz(x0.tail<4>()).toRotationMatrix(), up, n, p0, h, H);
    EXPECT_TRUE(test::check_jacobian("H", h_of, x0, H, pose, test::Layout::euclidean(3), tight)) << "trial " << trial;
    // On the plane and upright, h = 0.
    const Eigen::Quaterniond q = math::quat_from_wxyz(x0.tail<4>());
    planar_motion_measurement(p0, q.toRotationMatrix(), up, (q * up).normalized(), p0, h, H);
    EXPECT_LT(h.norm(), 1e-12);
  }
}

// A constant-velocity robot (tangent [δp δθ v ω]) whose mean and covariance the test sets.
struct OneRobot {
  slam::World world;
  slam::Map* map = nullptr;
  slam::Robot* robot = nullptr;
  OneRobot() {
    map = &world.add_map();
    Eigen::VectorXd x0 = Eigen::VectorXd::Zero(13);
    x0[3] = 1.0;  // q = identity (w x y z)
    robot = &map->add_robot(std::make_unique<slam::ConstantVelocityRobot>(models::ConstantVelocityParams{}), x0,
                            Eigen::MatrixXd::Zero(12, 12), 0);
  }
  void set(const Vector3d& p, const Eigen::Quaterniond& q, double var_p, double var_theta) {
    auto x = map->state().mean(robot->block());
    x.head<3>() = p;
    x.segment<4>(3) = math::quat_to_wxyz(q);
    auto P = map->state().cov(robot->block(), robot->block());
    P.setZero();
    P.diagonal().head<3>().setConstant(var_p);
    P.diagonal().segment<3>(3).setConstant(var_theta);
    P.diagonal().tail<6>().setConstant(0.1);
  }
};

slam::RawData raw_at(TimeNs t) {
  slam::RawData raw;
  raw.t = t;
  return raw;
}

// A camera: the hook acts after the steps of sensors that observe landmarks.
slam::PinholeSensor some_camera() { return slam::PinholeSensor("cam0", support::vga_camera(), math::Pose{}); }

TEST(PlanarMotion, TheFirstImageSetsThePlaneThenOneUpdateATimeIsTheClosedFormKalmanStep) {
  OneRobot r;
  PlanarMotionOptions o;
  o.enabled = true;
  o.height_std = 0.03;
  o.tilt_std = 0.01;
  PlanarMotionUpdater u;
  u.add_robot(*r.robot, o);
  RingBuffer<slam::ImuData> no_inputs{4};
  slam::FrameStats stats;
  const slam::PinholeSensor cam = some_camera();
  // The first image: the plane through the start (the origin), normal the robot's z axis; nothing corrected.
  u.after_step(*r.map, *r.robot, cam, raw_at(0), no_inputs, stats);
  ASSERT_TRUE(u.plane(*r.robot).has_value());
  EXPECT_LT((u.plane(*r.robot)->n - Vector3d::UnitZ()).norm(), 1e-12);
  EXPECT_EQ(u.updates(), 0);

  // Raised by dz and rolled by δ about x, with independent variances: each row is a scalar Kalman step.
  const double dz = 0.2, delta = 0.15, var_p = 0.04, var_t = 0.09;
  r.set(Vector3d(0.5, -0.3, dz), math::exp_so3(Vector3d(delta, 0.0, 0.0)), var_p, var_t);
  u.after_step(*r.map, *r.robot, cam, raw_at(50'000'000), no_inputs, stats);
  EXPECT_EQ(u.updates(), 1);
  // The same time's second image (a stereo pair): the robot was told already.
  const math::Pose once = r.robot->pose();
  u.after_step(*r.map, *r.robot, cam, raw_at(50'000'000), no_inputs, stats);
  EXPECT_EQ(u.updates(), 1);
  EXPECT_EQ(r.robot->pose().p, once.p);
  const math::Pose T = r.robot->pose();
  const double rh = o.height_std * o.height_std, rt = o.tilt_std * o.tilt_std;
  // Height: z ← dz − var_p/(var_p + r_h) dz, variance var_p r_h / (var_p + r_h); x and y untouched.
  EXPECT_NEAR(T.p.z(), dz * rh / (var_p + rh), 1e-12);
  EXPECT_NEAR(T.p.x(), 0.5, 1e-12);
  EXPECT_NEAR(T.p.y(), -0.3, 1e-12);
  const auto P = r.map->state().cov(r.robot->block(), r.robot->block());
  EXPECT_NEAR(P(2, 2), var_p * rh / (var_p + rh), 1e-12);
  // Roll: the up axis's tilt is −sin δ along the plane's second direction, with slope −cos δ in δθx, so
  // δ ← δ − var_t cos δ sin δ / (cos²δ var_t + r_t) (the same axis: the angles add); pitch and yaw stay 0.
  const double c = std::cos(delta), s = std::sin(delta);
  const Vector3d theta = math::log_so3(T.q);
  EXPECT_NEAR(theta.x(), delta - var_t * c * s / (c * c * var_t + rt), 1e-12);
  EXPECT_NEAR(theta.y(), 0.0, 1e-12);
  EXPECT_NEAR(theta.z(), 0.0, 1e-12);
  EXPECT_NEAR(P(3, 3), var_t * rt / (c * c * var_t + rt), 1e-12);
  EXPECT_NEAR(P(4, 4), var_t * rt / (var_t + rt), 1e-12);  // pitch: measured with slope 1 at h = 0
  EXPECT_NEAR(P(5, 5), var_t, 1e-12);                      // yaw: the plane says nothing of it
}

TEST(PlanarMotion, OnlyTheRobotsAddedAndOnlyAfterImages) {
  OneRobot held, other;
  PlanarMotionUpdater u;
  u.add_robot(*held.robot, PlanarMotionOptions{});
  RingBuffer<slam::ImuData> no_inputs{4};
  slam::FrameStats stats;
  const slam::PinholeSensor cam = some_camera();
  const slam::AbsoluteSensor gps("gps", slam::AbsoluteSensor::Kind::Position, math::Pose{});
  for (OneRobot* r : {&held, &other}) u.after_step(*r->map, *r->robot, cam, raw_at(0), no_inputs, stats);
  EXPECT_TRUE(u.plane(*held.robot).has_value());
  EXPECT_FALSE(u.plane(*other.robot).has_value());  // not added: left alone
  held.set(Vector3d(0.0, 0.0, 1.0), Eigen::Quaterniond::Identity(), 0.04, 0.09);
  other.set(Vector3d(0.0, 0.0, 1.0), Eigen::Quaterniond::Identity(), 0.04, 0.09);
  // An absolute fix's step is not an image: nothing.
  u.after_step(*held.map, *held.robot, gps, raw_at(25'000'000), no_inputs, stats);
  EXPECT_EQ(held.robot->pose().p.z(), 1.0);
  for (OneRobot* r : {&held, &other}) u.after_step(*r->map, *r->robot, cam, raw_at(50'000'000), no_inputs, stats);
  EXPECT_LT(held.robot->pose().p.z(), 1.0);
  EXPECT_EQ(other.robot->pose().p.z(), 1.0);
  EXPECT_EQ(u.updates(), 1);
}

TEST(PlanarMotion, ARestartedRobotIsToldAgainAtTheSameTimeOnTheSamePlane) {
  OneRobot r;
  PlanarMotionUpdater u;
  u.add_robot(*r.robot, PlanarMotionOptions{});
  RingBuffer<slam::ImuData> no_inputs{4};
  slam::FrameStats stats;
  const slam::PinholeSensor cam = some_camera();
  u.after_step(*r.map, *r.robot, cam, raw_at(0), no_inputs, stats);
  r.set(Vector3d(0.0, 0.0, 1.0), Eigen::Quaterniond::Identity(), 0.04, 0.09);
  u.after_step(*r.map, *r.robot, cam, raw_at(50'000'000), no_inputs, stats);
  EXPECT_EQ(u.updates(), 1);
  // The health monitor restarts the robot at 50 ms (System::start) and replays that time's image: the new state is
  // told, on the plane of the first image.
  r.set(Vector3d(0.0, 0.0, 1.0), Eigen::Quaterniond::Identity(), 0.04, 0.09);
  u.on_start(*r.robot, slam::RobotStart{});
  u.after_step(*r.map, *r.robot, cam, raw_at(50'000'000), no_inputs, stats);
  EXPECT_EQ(u.updates(), 2);
  EXPECT_LT(r.robot->pose().p.z(), 1.0);
  EXPECT_LT((u.plane(*r.robot)->p0 - Vector3d::Zero()).norm(), 1e-12);
}

TEST(PlanarMotionOptions, BadValuesAndUnknownKeysAreErrorsNamingTheKey) {
  const auto error_of = [](const std::string& yaml) -> std::string {
    try {
      PlanarMotionOptions o;
      read_planar_motion(YamlMap(YAML::Load(yaml), "cfg.yaml"), o);
      o.validate();
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(error_of("{up: [0, 0, 0]}").find("up"), std::string::npos);
  EXPECT_NE(error_of("{up: [0, .nan, 1]}").find("up"), std::string::npos);
  EXPECT_NE(error_of("{height_std: 0}").find("height_std"), std::string::npos);
  EXPECT_NE(error_of("{tilt_std: -1}").find("tilt_std"), std::string::npos);
  EXPECT_NE(error_of("{tilt: 0.1}").find("tilt"), std::string::npos);
  EXPECT_EQ(error_of("{enabled: true, up: [1, 0, 0], height_std: 0.05, tilt_std: 0.03}"), "");
  // What the configuration dump writes reads back the same.
  PlanarMotionOptions a;
  a.enabled = true;
  a.up = Vector3d(1.0, 0.0, 0.0);
  a.height_std = 0.05;
  PlanarMotionOptions b;
  read_planar_motion(YamlMap(planar_motion_to_yaml(a), "dump.yaml"), b);
  EXPECT_EQ(b.enabled, true);
  EXPECT_EQ(b.up, a.up);
  EXPECT_EQ(b.height_std, 0.05);
  EXPECT_EQ(b.tilt_std, a.tilt_std);
}

}  // namespace
}  // namespace rtslam::strategies
