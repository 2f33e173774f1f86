// Monocular SLAM on an odometry-driven robot (slam/robot: odometry) on the simulator's rendered handheld sequence
// with its synthesized wheel odometry (sim/odometry.hpp, default noise): the odometry gives the scale, the camera
// bounds the drift. Issue 15 acceptance "odometry robot ... has a convergence test": the trajectory error after an
// SE(3) alignment (no scale) is below 2 % of the path and below the odometry's own dead reckoning over the same
// readings, and the Sim(3) scale is within 3 % of 1.
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

TEST(OdometrySlam, MonocularCameraBoundsTheOdometryDriftAtTheOdometryScale) {
  ImageSlamOptions o = load_image_slam_config(kConfig);
  o.robot = "odometry";
  sim::SimConfig sc = sim::SimConfig::load(o.sim_preset);
  sc.seed = o.seed;
  sc.duration_s = 20.0;
  sc.odometry.enabled = true;  // default noise, the filter's default model
  const auto simulation = sim::Simulation::create(sc);
  io::Dataset ds = simulation->make_dataset();
  const ImageSlamResult r = run_image_slam(ds, o);
  const eval::EvalResult slam = evaluate(r.estimate, *ds.ground_truth);
  const eval::EvalResult odo = evaluate(dead_reckoning(simulation->odometry()), *ds.ground_truth);
  std::printf("odometry + mono, %zu frames over %.1f m: SE(3) ATE %.4f m (%.2f %%), Sim(3) scale %.4f; odometry "
              "alone: ATE %.4f m (%.2f %%); %d landmarks, %d resets\n",
              r.frames.size(), slam.path_length_m, slam.ate.trans_m.rmse, 100.0 * slam.ate.trans_m.rmse / slam.path_length_m,
              slam.sim3_scale, odo.ate.trans_m.rmse, 100.0 * odo.ate.trans_m.rmse / odo.path_length_m,
              r.landmarks_final, r.resets);
  EXPECT_EQ(r.resets, 0);
  EXPECT_LT(slam.ate.trans_m.rmse, 0.02 * slam.path_length_m);
  EXPECT_LT(slam.ate.trans_m.rmse, odo.ate.trans_m.rmse);
  EXPECT_NEAR(slam.sim3_scale, 1.0, 0.03);
}

}  // namespace
}  // namespace rtslam::pipeline
