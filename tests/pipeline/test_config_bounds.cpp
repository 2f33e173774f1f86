// Issue 17 item 1: initial states and the pipeline's config keys are checked for plausibility, with messages naming
// the file (or section) and the key.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "rtslam/core/error.hpp"
#include "rtslam/pipeline/config_common.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/pipeline/inertial_init.hpp"
#include "rtslam/pipeline/known_landmarks.hpp"

namespace rtslam::pipeline {
namespace {

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}

// A zero quaternion in initial_state.json gave all-zero attitudes in the output.
TEST(InitialState, AZeroQuaternionIsAnErrorNamingTheFile) {
  const auto dir = std::filesystem::temp_directory_path() / "rtslam_config_bounds_zero_q";
  std::filesystem::create_directories(dir);
  std::string pxx = "[";
  for (int r = 0; r < 13; ++r) pxx += std::string(r ? "," : "") + "[0,0,0,0,0,0,0,0,0,0,0,0,0]";
  std::ofstream(dir / "initial_state.json") << R"({"xv": [0, 0, -0.6, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0], "pxx": )" << pxx
                                            << R"(], "features": [{"yi": [0.1, 0.0, 0.0]}]})";
  EXPECT_EQ(error_of([&] { load_known_landmarks(dir.string(), "robot"); }),
            (dir / "initial_state.json").string() +
                ": |q| (xv[3..6], w x y z) = 0 must be 1 within 0.001 (a unit quaternion)");
  std::filesystem::remove_all(dir);
}

TEST(InitialState, NonSymmetricOrIndefiniteCovariancesAreRefused) {
  Eigen::VectorXd x = Eigen::VectorXd::Zero(13);
  x[3] = 1.0;
  Eigen::MatrixXd P = 0.01 * Eigen::MatrixXd::Identity(13, 13);
  EXPECT_EQ(error_of([&] { check_initial_state(x, P, 3, "s.json"); }), "(no error)");
  P(0, 1) = 0.005;
  EXPECT_NE(error_of([&] { check_initial_state(x, P, 3, "s.json"); }).find("symmetric"), std::string::npos);
  P(1, 0) = 0.005;
  P(2, 2) = -1.0;
  EXPECT_NE(error_of([&] { check_initial_state(x, P, 3, "s.json"); }).find("smallest eigenvalue of pxx = -1"),
            std::string::npos);
  P(2, 2) = 0.0;  // a zero variance is a known value (the gauge)
  EXPECT_EQ(error_of([&] { check_initial_state(x, P, 3, "s.json"); }), "(no error)");
  x[3] = 1.01;
  EXPECT_NE(error_of([&] { check_initial_state(x, P, 3, "s.json"); }).find("|q|"), std::string::npos);
}

TEST(SlamBounds, StateCapacityAndOtherSlamKeysHaveUpperBounds) {
  ImageSlamOptions o;
  EXPECT_EQ(error_of([&] { validate_slam_bounds(o); }), "(no error)");
  o.state_capacity = 100000;
  EXPECT_NE(error_of([&] { validate_slam_bounds(o); }).find("slam: state_capacity = 100000 must be in [100, 10000]"),
            std::string::npos);
  o.state_capacity = 600;
  o.rate_hz = 1e-300;
  EXPECT_NE(error_of([&] { validate_slam_bounds(o); }).find("slam: rate_hz = 1e-300"), std::string::npos);
}

TEST(OdometryOptions, KeysAreReadWrittenAndBounded) {
  ImageSlamOptions o;
  apply_image_slam_config(YAML::Load("slam: {robot: odometry}\nodometry: {sigma_p: 0.02, k_theta: 0.1}"), "test.yaml",
                          o);
  EXPECT_EQ(o.robot, "odometry");
  EXPECT_EQ(o.odometry.sigma_p, 0.02);
  EXPECT_EQ(o.odometry.k_theta, 0.1);
  ImageSlamOptions back;
  apply_image_slam_config(to_yaml(o), "dump", back);
  EXPECT_EQ(back.odometry.sigma_p, 0.02);
  EXPECT_EQ(back.odometry.k_theta, 0.1);
  EXPECT_EQ(error_of([&] { apply_image_slam_config(YAML::Load("odometry: {k_p: 11}"), "test.yaml", o); }),
            "test.yaml: odometry/k_p = 11 must be in [0, 10] m/sqrt(m)");
  EXPECT_NE(error_of([&] { apply_image_slam_config(YAML::Load("odometry: {k: 1}"), "test.yaml", o); }).find("k"),
            std::string::npos);
}

TEST(ImuOptionsBounds, PriorsAndSaturationsHaveUpperBounds) {
  InertialOptions o;
  EXPECT_EQ(error_of([&] { o.validate(); }), "(no error)");
  o.velocity_std_motion = 1e9;
  EXPECT_NE(error_of([&] { o.validate(); }).find("imu: velocity_std_motion = 1000000000 must be in (0, 100] m/s"),
            std::string::npos);
  o.velocity_std_motion = 1.0;
  o.accel_saturation = 1e30;
  EXPECT_NE(error_of([&] { o.validate(); }).find("accel_saturation"), std::string::npos);
}

}  // namespace
}  // namespace rtslam::pipeline
