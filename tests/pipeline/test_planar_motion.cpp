// planar_motion on the simulator's ground robot (one camera + wheel odometry, no IMU): the sequence whose attitude
// the filter loses unnoticed without it (seed 16: its up axis turns by 7.3° 3-5 s into the run,
// docs/odometry-scale.md) keeps its up axis with it. The floor of the `ground` preset is flat, the robot frame's x
// axis is up.
#include <algorithm>
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "rtslam/pipeline/image_slam.hpp"

namespace rtslam::pipeline {
namespace {

struct Tilt {
  double max_deg = 0.0;
  ImageSlamResult result;
};

// The largest angle between the estimated up axis and its direction at the first pose, over `duration_s` of the
// ground preset's seed 16 (its attitude turns between 3 and 5 s).
Tilt run_ground(bool planar, double duration_s) {
  ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/sim_mono.yaml");
  o.sim_preset = "ground";
  o.seed = 16;
  o.robot = "odometry";
  o.sim_duration_s = 20.0;  // the 20 s sequence (the preset's laps depend on the duration), its first seconds
  o.planar_motion.enabled = planar;
  o.planar_motion.up = Eigen::Vector3d::UnitX();
  io::Dataset ds = make_sim_dataset(o);
  ds.source = std::make_unique<io::WindowSource>(std::move(ds.source), 0.0, duration_s);
  Tilt t;
  t.result = run_image_slam(ds, o);
  const auto& poses = t.result.estimate.poses;
  EXPECT_FALSE(poses.empty());
  if (poses.empty()) return t;
  const Eigen::Vector3d up0 = poses.front().q_WR * Eigen::Vector3d::UnitX();
  for (const auto& p : poses) {
    const double c = std::clamp(up0.dot(p.q_WR * Eigen::Vector3d::UnitX()), -1.0, 1.0);
    t.max_deg = std::max(t.max_deg, std::acos(c) * 180.0 / M_PI);
  }
  std::printf("ground seed 16, %.0f s, planar_motion %s: %zu poses, largest tilt %.2f deg, %d reset(s)\n", duration_s,
              planar ? "on" : "off", poses.size(), t.max_deg, t.result.resets);
  return t;
}

TEST(PlanarMotionGround, TheGroundRobotKeepsItsUpAxisWhereOneCameraAndOdometryLoseIt) {
  const Tilt on = run_ground(true, 8.0);
  EXPECT_LT(on.max_deg, 1.0);
  EXPECT_EQ(on.result.resets, 0);
  // Without it the same 8 s tilt by degrees (a record of the failure; the front end or the filter may one day keep
  // this sequence upright on their own: then this line goes, the check above stays).
  const Tilt off = run_ground(false, 8.0);
  EXPECT_GT(off.max_deg, 3.0);
}

}  // namespace
}  // namespace rtslam::pipeline
