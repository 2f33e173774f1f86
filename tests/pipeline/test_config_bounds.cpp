// Issue 17 item 1: initial states and the pipeline's config keys are checked for plausibility, with messages naming
// the file (or section) and the key.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/pipeline/config_common.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/pipeline/inertial_init.hpp"
#include "rtslam/pipeline/known_landmarks.hpp"
#include "rtslam/sim/simulation.hpp"

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
  apply_image_slam_config(YAML::Load("slam: {robot: odometry}\nodometry: {sigma_p: 0.02, k_theta: 0.1, rescale: off, "
                                     "rescale_window: 2, rescale_max_se: 0.05, rescale_min_z: 3}"),
                          "test.yaml", o);
  EXPECT_EQ(o.robot, "odometry");
  EXPECT_EQ(o.odometry.sigma_p, 0.02);
  EXPECT_EQ(o.odometry.k_theta, 0.1);
  ImageSlamOptions back;
  apply_image_slam_config(to_yaml(o), "dump", back);
  EXPECT_EQ(back.odometry.sigma_p, 0.02);
  EXPECT_EQ(back.odometry.k_theta, 0.1);
  EXPECT_EQ(back.odometry_rescale, "off");
  EXPECT_EQ(back.odometry_scale.window_m, 2.0);
  EXPECT_EQ(back.odometry_scale.max_se, 0.05);
  EXPECT_EQ(back.odometry_scale.min_z, 3.0);
  ImageSlamOptions fresh;
  EXPECT_EQ(error_of([&] { apply_image_slam_config(YAML::Load("odometry: {rescale: maybe}"), "test.yaml", fresh); }),
            "test.yaml: odometry/rescale = 'maybe' must be auto, on or off");
  ImageSlamOptions fresh2;
  EXPECT_EQ(
      error_of([&] { apply_image_slam_config(YAML::Load("odometry: {rescale_window: 0}"), "test.yaml", fresh2); }),
      "test.yaml: odometry/rescale_window = 0 must be in (0, 1000] m");
  EXPECT_EQ(error_of([&] { apply_image_slam_config(YAML::Load("odometry: {k_p: 11}"), "test.yaml", o); }),
            "test.yaml: odometry/k_p = 11 must be in [0, 10] m/sqrt(m)");
  EXPECT_NE(error_of([&] { apply_image_slam_config(YAML::Load("odometry: {k: 1}"), "test.yaml", o); }).find("k"),
            std::string::npos);
}

TEST(PlanarMotionOptions, KeysAreReadWrittenBoundedAndRefusedWithTheConstrainedFilter) {
  ImageSlamOptions o;
  apply_image_slam_config(
      YAML::Load("planar_motion: {enabled: true, up: [1, 0, 0], height_std: 0.05, tilt_std: 0.03}"), "test.yaml", o);
  EXPECT_TRUE(o.planar_motion.enabled);
  EXPECT_EQ(o.planar_motion.up, Eigen::Vector3d::UnitX());
  ImageSlamOptions back;
  apply_image_slam_config(to_yaml(o), "dump", back);
  EXPECT_TRUE(back.planar_motion.enabled);
  EXPECT_EQ(back.planar_motion.up, Eigen::Vector3d::UnitX());
  EXPECT_EQ(back.planar_motion.height_std, 0.05);
  EXPECT_EQ(back.planar_motion.tilt_std, 0.03);
  ImageSlamOptions fresh;
  EXPECT_EQ(error_of([&] { apply_image_slam_config(YAML::Load("planar_motion: {tilt_std: 2}"), "test.yaml", fresh); }),
            "test.yaml: planar_motion: tilt_std = 2 must be in (0, 1] rad");
  ImageSlamOptions oc;
  EXPECT_NE(error_of([&] {
              apply_image_slam_config(YAML::Load("slam: {consistency: oc}\nplanar_motion: {enabled: true}"),
                                      "test.yaml", oc);
            }).find("planar_motion with slam/consistency = oc"),
            std::string::npos);
  ImageSlamOptions gps;
  EXPECT_NE(error_of([&] {
              apply_image_slam_config(YAML::Load("position_sensor: {enabled: true}\nplanar_motion: {enabled: true}"),
                                      "test.yaml", gps);
            }).find("planar_motion with position_sensor/world = align"),
            std::string::npos);
  ImageSlamOptions gps_start;
  EXPECT_EQ(error_of([&] {
              apply_image_slam_config(
                  YAML::Load("position_sensor: {enabled: true, world: start}\nplanar_motion: {enabled: true}"),
                  "test.yaml", gps_start);
            }),
            "(no error)");
}

TEST(ZeroVelocityOptions, RefusedWithTheOdometryRobotWhoseStateHasNoVelocity) {
  ImageSlamOptions odo;
  EXPECT_NE(error_of([&] {
              apply_image_slam_config(YAML::Load("slam: {robot: odometry}\nzero_velocity: {enabled: true}"),
                                      "test.yaml", odo);
            }).find("zero_velocity with slam/robot = odometry"),
            std::string::npos);
  for (const char* robot : {"constant_velocity", "inertial"}) {
    ImageSlamOptions ok;
    EXPECT_EQ(error_of([&] {
                apply_image_slam_config(
                    YAML::Load(fmt::format("slam: {{robot: {}}}\nzero_velocity: {{enabled: true}}", robot)),
                    "test.yaml", ok);
              }),
              "(no error)")
        << robot;
  }
}

TEST(OdometryOptions, RescaleOnWithAnAbsoluteSensorIsRefused) {
  // The absolute sensor gives the map's scale: keeping it at the odometry's would fight it.
  ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/sim_mono.yaml");
  o.robot = "odometry";
  o.odometry_rescale = "on";
  o.position_sensor.enabled = true;
  o.position_sensor.world = "start";
  sim::SimConfig sc = sim::SimConfig::load(o.sim_preset);
  sc.duration_s = 0.5;
  sc.odometry.enabled = true;
  sc.gps.enabled = true;
  io::Dataset ds = sim::Simulation::create(sc)->make_dataset();
  EXPECT_EQ(error_of([&] { run_image_slam(ds, o); }),
            "odometry/rescale = on cannot be used with an absolute sensor (position_sensor, pose_sensor): the sensor "
            "gives the map's scale");
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

namespace rtslam::pipeline {
namespace {

// The absolute sensors' sections (strategies/absolute.hpp, docs/configuration.md): every key read, written back
// identically, and a bad value is a one-line error naming the file and the key.
TEST(AbsoluteSensorConfig, KeysAreReadAndRoundTrip) {
  ImageSlamOptions o;
  apply_image_slam_config(YAML::Load("{slam: {robot: inertial},"
                                     " position_sensor: {enabled: true, sigma: 0.3, lever_arm: [0.1, -0.05, 0.2],"
                                     "   gate: 20, world: align, align_yaw_std_deg: 2, align_min_fixes: 25},"
                                     " pose_sensor: {enabled: true, sigma: 0.002, sigma_deg: 0.2, lever_arm: [0, 0, 0.1],"
                                     "   rotation_deg: [10, -20, 90], world: start}}"),
                          "abs.yaml", o);
  EXPECT_TRUE(o.position_sensor.enabled);
  EXPECT_EQ(o.position_sensor.sigma_m, 0.3);
  EXPECT_EQ(o.position_sensor.lever_arm, Eigen::Vector3d(0.1, -0.05, 0.2));
  EXPECT_EQ(o.position_sensor.gate, 20.0);
  EXPECT_EQ(o.position_sensor.align_yaw_std_deg, 2.0);
  EXPECT_EQ(o.position_sensor.align_min_fixes, 25);
  EXPECT_TRUE(o.pose_sensor.enabled);
  EXPECT_EQ(o.pose_sensor.sigma_m, 0.002);
  EXPECT_EQ(o.pose_sensor.sigma_deg, 0.2);
  EXPECT_EQ(o.pose_sensor.rotation_deg, Eigen::Vector3d(10, -20, 90));
  EXPECT_EQ(o.pose_sensor.world, "start");
  EXPECT_EQ(o.pose_sensor.T_RS().p, Eigen::Vector3d(0, 0, 0.1));
  ImageSlamOptions back;
  apply_image_slam_config(to_yaml(o), "round trip", back);
  EXPECT_EQ(YAML::Dump(to_yaml(back)), YAML::Dump(to_yaml(o)));
}

TEST(AbsoluteSensorConfig, BadValuesAreOneLineErrorsNamingFileAndKey) {
  const auto err = [](const std::string& yaml) {
    ImageSlamOptions o;
    return error_of([&] { apply_image_slam_config(YAML::Load(yaml), "abs.yaml", o); });
  };
  for (const std::string& e : {err("{position_sensor: {sigma: -1}}"), err("{pose_sensor: {sigma_deg: 500}}"),
                               err("{position_sensor: {world: gps}}"), err("{pose_sensor: {sigma_m: 1}}"),
                               err("{position_sensor: {align_min_fixes: 1}}"),
                               err("{position_sensor: {enabled: true}}")}) {
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
    EXPECT_NE(e, "(no error)");
  }
  EXPECT_EQ(err("{position_sensor: {sigma: -1}}"), "abs.yaml: position_sensor: sigma = -1 must be in (0, 1e4] m");
  EXPECT_NE(err("{pose_sensor: {sigma_deg: 500}}").find("abs.yaml: pose_sensor: sigma_deg = 500"), std::string::npos);
  EXPECT_NE(err("{position_sensor: {world: gps}}").find("abs.yaml: position_sensor: world = 'gps'"), std::string::npos);
  EXPECT_NE(err("{pose_sensor: {sigma_m: 1}}").find("abs.yaml"), std::string::npos);  // an unknown key
  EXPECT_NE(err("{pose_sensor: {sigma_m: 1}}").find("sigma_m"), std::string::npos);
  // Aligning with a position only needs gravity: the inertial robot.
  EXPECT_NE(err("{position_sensor: {enabled: true}}").find("position_sensor/world = align needs slam/robot = inertial"),
            std::string::npos);
}

}  // namespace
}  // namespace rtslam::pipeline
