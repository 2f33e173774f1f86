// The builder's robot-level hooks (pipeline/builder.hpp): planar_motion and zero_velocity are one hook each per
// System however many robots use them, and each is also one of the System's observers, so that the System tells it
// of a robot's restart (the plane is told again; a rest verdict of before the restart is forgotten). The hooks' own
// tests (tests/strategies) call on_start themselves; this one checks that a built System will.
#include <gtest/gtest.h>

#include <algorithm>

#include "rtslam/core/error.hpp"
#include "rtslam/pipeline/builder.hpp"
#include "rtslam/strategies/planar_motion.hpp"
#include "rtslam/strategies/zero_velocity.hpp"

namespace rtslam::pipeline {
namespace {

// A camera with an IMU, as the inertial robot needs (the values are a plain 752x480 camera's and the ADIS16448's).
io::Rig camera_imu_rig() {
  io::Rig rig;
  io::CameraCalibration cam;
  cam.name = "cam0";
  cam.width = 752;
  cam.height = 480;
  cam.rate_hz = 20.0;
  cam.fx = cam.fy = 458.0;
  cam.cx = 376.0;
  cam.cy = 240.0;
  rig.cameras.push_back(cam);
  io::ImuCalibration imu;
  imu.rate_hz = 200.0;
  imu.gyro_noise_density = 1.7e-4;
  imu.gyro_random_walk = 1.9e-5;
  imu.accel_noise_density = 2.0e-3;
  imu.accel_random_walk = 3.0e-3;
  rig.imu = imu;
  return rig;
}

long times_observing(const slam::System& system, const slam::Observer* observer) {
  return std::count(system.observers().begin(), system.observers().end(), observer);
}

TEST(Builder, RobotHooksAreOnePerSystemAndObserveIt) {
  ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/euroc_mono_imu.yaml");
  o.consistency = "none";  // planar_motion is refused with the constrained filter
  o.zero_velocity.enabled = true;
  o.planar_motion.enabled = true;
  o.validate();
  const io::Rig rig = camera_imu_rig();
  const BuildContext context{o, rig, "builder test"};
  BuiltSystem built = build_system(context);
  ASSERT_NE(built.zero_velocity, nullptr);
  ASSERT_NE(built.planar_motion, nullptr);
  strategies::ZeroVelocityUpdater* const zero_velocity = built.zero_velocity;
  strategies::PlanarMotionUpdater* const planar_motion = built.planar_motion;

  Registry::builtin().add_robot_to(built, context);  // a second robot with the same options: the same two hooks
  ASSERT_EQ(built.robots.size(), 2u);
  EXPECT_EQ(built.zero_velocity, zero_velocity);
  EXPECT_EQ(built.planar_motion, planar_motion);
  // Told of every (re)start, once each.
  EXPECT_EQ(times_observing(*built.system, zero_velocity), 1);
  EXPECT_EQ(times_observing(*built.system, planar_motion), 1);
  // Both robots are the hooks' already (a robot is added to a hook once: a second time is refused).
  for (const BuiltRobot& r : built.robots) {
    EXPECT_THROW(zero_velocity->add_robot(*r.robot, o.zero_velocity), ConfigError);
  }
}

TEST(Builder, NoHooksWhenTheOptionsAreOff) {
  ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/euroc_mono_imu.yaml");
  o.zero_velocity.enabled = false;
  o.planar_motion.enabled = false;
  const io::Rig rig = camera_imu_rig();
  const BuiltSystem built = build_system(BuildContext{o, rig, "builder test"});
  EXPECT_EQ(built.zero_velocity, nullptr);
  EXPECT_EQ(built.planar_motion, nullptr);
  EXPECT_TRUE(built.system->observers().empty());
}

}  // namespace
}  // namespace rtslam::pipeline
