// SLAM on an odometry-driven robot (slam/robot: odometry) on the simulator's rendered sequences with their
// synthesized wheel odometry (sim/odometry.hpp, default noise). Issue 15 acceptance "odometry robot ... has a
// convergence test":
//  - one camera on the hand-held sequence: the odometry gives the scale, the camera bounds the drift: the trajectory
//    error after an SE(3) alignment (no scale) below 2 % of the path and below the odometry's own dead reckoning over
//    the same readings, the Sim(3) scale within 3 % of 1 (the map's scale kept at the odometry's: odometry/rescale,
//    docs/odometry-scale.md);
//  - two cameras on the `ground` preset (a wheeled robot, its natural use): the error below half the dead
//    reckoning's and 1 % of the path, the scale within 1 %.
#include <gtest/gtest.h>

#include <cstdio>

#include "rtslam/eval/metrics.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/sim/simulation.hpp"

namespace rtslam::pipeline {
namespace {

const std::string kConfig = RTSLAM_SOURCE_DIR "/config/sim_mono.yaml";

// The readings composed from the first one's start (the world frame of the dead reckoning: the start pose).
Trajectory dead_reckoning(const std::vector<sim::SynthOdometry>& odometry) {
  Trajectory t;
  math::Pose T;
  t.poses.push_back(StampedPose{});
  t.poses.back().t = odometry.front().t_from;
  for (const sim::SynthOdometry& o : odometry) {
    T = T * math::Pose{math::exp_so3(o.dtheta), o.dp};
    StampedPose p;
    p.t = o.t;
    p.p_WR = T.p;
    p.q_WR = T.q;
    t.poses.push_back(p);
  }
  return t;
}

eval::EvalResult evaluate(const Trajectory& est, const Trajectory& gt) {
  eval::EvalOptions eo;
  eo.align = eval::Alignment::Se3;
  eo.with_rpe = false;
  return eval::evaluate(est, gt, eo);
}

struct OdometryRun {
  ImageSlamResult result;
  eval::EvalResult slam, odometry;
};

// 20 s of the simulator preset of `config` (or `preset` when given) with the robot driven by its wheel odometry.
OdometryRun run_with_odometry(const std::string& config, const std::string& preset = {}) {
  ImageSlamOptions o = load_image_slam_config(config);
  o.robot = "odometry";
  if (!preset.empty()) o.sim_preset = preset;
  sim::SimConfig sc = sim::SimConfig::load(o.sim_preset);
  sc.seed = o.seed;
  sc.duration_s = 20.0;
  sc.odometry.enabled = true;  // default noise, the filter's default model
  if (o.camera_indices().size() > 1) sc.stereo = true;
  const auto simulation = sim::Simulation::create(sc);
  io::Dataset ds = simulation->make_dataset();
  OdometryRun r;
  r.result = run_image_slam(ds, o);
  r.slam = evaluate(r.result.estimate, *ds.ground_truth);
  r.odometry = evaluate(dead_reckoning(simulation->odometry()), *ds.ground_truth);
  std::printf("%s%s, odometry + %zu camera(s), %zu frames over %.1f m: SE(3) ATE %.4f m (%.2f %%), Sim(3) scale "
              "%.4f; odometry alone: ATE %.4f m (%.2f %%); %d landmarks, %d resets\n",
              config.c_str(), preset.empty() ? "" : (" on " + preset).c_str(), o.camera_indices().size(),
              r.result.frames.size(), r.slam.path_length_m, r.slam.ate.trans_m.rmse,
              100.0 * r.slam.ate.trans_m.rmse / r.slam.path_length_m, r.slam.sim3_scale, r.odometry.ate.trans_m.rmse,
              100.0 * r.odometry.ate.trans_m.rmse / r.odometry.path_length_m, r.result.landmarks_final,
              r.result.resets);
  return r;
}

TEST(OdometrySlam, MonocularCameraBoundsTheOdometryDriftAtTheOdometryScale) {
  const OdometryRun r = run_with_odometry(kConfig);
  EXPECT_EQ(r.result.resets, 0);
  EXPECT_LT(r.slam.ate.trans_m.rmse, 0.02 * r.slam.path_length_m);
  EXPECT_LT(r.slam.ate.trans_m.rmse, r.odometry.ate.trans_m.rmse);
  EXPECT_NEAR(r.slam.sim3_scale, 1.0, 0.03);
}

TEST(OdometrySlam, TwoCamerasBoundAGroundRobotsOdometryDrift) {
  const OdometryRun r = run_with_odometry(RTSLAM_SOURCE_DIR "/config/sim_stereo.yaml", "ground");
  EXPECT_EQ(r.result.resets, 0);
  EXPECT_GT(r.slam.path_length_m, 8.0);  // laps at 0.5 m/s
  EXPECT_LT(r.slam.ate.trans_m.rmse, 0.01 * r.slam.path_length_m);
  EXPECT_LT(r.slam.ate.trans_m.rmse, 0.5 * r.odometry.ate.trans_m.rmse);
  EXPECT_NEAR(r.slam.sim3_scale, 1.0, 0.01);
}

}  // namespace
}  // namespace rtslam::pipeline
