// Absolute sensors end to end on the rendered simulator (strategies/absolute.hpp, sim/absolute.hpp). The estimator's
// world frame is the sensor's (the map is moved there from the first fixes), so every error below is against the
// ground truth WITHOUT any alignment.
//  - GPS-like position at 5 Hz with 0.5 m noise (lever arm 0.1/−0.05/0.2 m), fused with the camera and the IMU on
//    the hall sequence. Slow: the acceptance, ATE ≤ 0.3 m over 5 minutes (whole run, the start before the yaw is
//    known included), and the same over 45 s (the filter takes the fixes over at ~34 s). Normal suite: 20 s with the
//    camera at 10 Hz and no supersampling in the renderer (rendering dominates the run time; tracking the hand-held
//    hall motion does not need 20 Hz): the fixes give the yaw and the error stays bounded.
//  - Motion-capture pose at 100 Hz with a lever arm and a rotation offset: the map is moved into the mocap frame at
//    the first pose, and the estimate follows the mocap frame to millimetres (normal suite: 4 s, camera at 10 Hz, no
//    supersampling).
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "rtslam/core/log.hpp"
#include "rtslam/pipeline/builder.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/sim/simulation.hpp"
#include "rtslam/strategies/absolute.hpp"

namespace rtslam::pipeline {
namespace {

struct HallSetup {
  double duration_s = 0.0;
  bool gps = false, mocap = false;
  bool light = false;  // camera at 10 Hz, no supersampling (the short tests)
};

struct HallRun {
  ImageSlamResult result;
  double ate_m = 0.0;         // RMSE of |p_est − p_true| over every estimate, no alignment
  double max_err_m = 0.0;     // after `after_s` from the first estimate
  double final_err_m = 0.0;
  double att_err_deg = 0.0;   // at the end
  double handover_s = -1.0;   // time of the first applied absolute correction after the first estimate
  int updates = 0, rejected = 0;
};

HallRun run_hall(const HallSetup& s, double after_s) {
  ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/sim_mono_imu.yaml");
  sim::SimConfig sc = sim::SimConfig::load("hall");
  sc.seed = o.seed;
  sc.duration_s = s.duration_s;
  if (s.light) {
    sc.camera.rate_hz = 10.0;
    sc.render.supersampling = 1;
  }
  const Eigen::Vector3d lever(0.10, -0.05, 0.20);  // antenna / marker body in R
  if (s.gps) {
    sc.gps.enabled = true;
    sc.gps.rate_hz = 5.0;
    sc.gps.sigma_m = 0.5;
    sc.gps.lever_arm = lever;
    o.position_sensor.enabled = true;
    o.position_sensor.sigma_m = 0.5;
    o.position_sensor.lever_arm = lever;
  }
  if (s.mocap) {
    sc.mocap.enabled = true;
    sc.mocap.lever_arm = lever;
    sc.mocap.rotation_deg = Eigen::Vector3d(10.0, -20.0, 90.0);
    o.pose_sensor.enabled = true;
    o.pose_sensor.sigma_m = sc.mocap.sigma_m;
    o.pose_sensor.sigma_deg = sc.mocap.sigma_deg;
    o.pose_sensor.lever_arm = lever;
    o.pose_sensor.rotation_deg = sc.mocap.rotation_deg;
  }
  const auto simulation = sim::Simulation::create(sc);
  io::Dataset ds = simulation->make_dataset();
  HallRun r;
  r.result = run_image_slam(ds, o);
  if (r.result.estimate.poses.empty()) return r;
  double sum = 0.0;
  const TimeNs t0 = r.result.estimate.poses.front().t;
  for (const StampedPose& p : r.result.estimate.poses) {
    const double e = (p.p_WR - simulation->trajectory().at(p.t).p_WR).norm();
    sum += e * e;
    if (p.t - t0 > from_seconds(after_s)) r.max_err_m = std::max(r.max_err_m, e);
  }
  r.ate_m = std::sqrt(sum / static_cast<double>(r.result.estimate.poses.size()));
  const StampedPose& last = r.result.estimate.poses.back();
  const sim::KinematicState truth = simulation->trajectory().at(last.t);
  r.final_err_m = (last.p_WR - truth.p_WR).norm();
  r.att_err_deg = math::log_so3(truth.q_WR.conjugate() * last.q_WR).norm() * 180.0 / M_PI;
  for (const slam::FrameStats& f : r.result.frames) {
    if (r.handover_s < 0.0 && f.absolute_updates > 0) r.handover_s = to_seconds(f.t - t0);
    r.updates += f.absolute_updates;
    r.rejected += f.absolute_rejected;
  }
  std::printf("%s hall %.0f s%s: ATE (no alignment) %.4f m, max error after %.1f s %.4f m, final %.4f m, attitude "
              "%.3f deg; first correction at %.1f s, %d applied, %d rejected; %d frames, health %s, %d resets\n",
              s.gps ? "GPS" : "mocap", s.duration_s, s.light ? " (10 Hz camera)" : "", r.ate_m, after_s, r.max_err_m,
              r.final_err_m, r.att_err_deg, r.handover_s, r.updates, r.rejected,
              static_cast<int>(r.result.frames.size()), slam::to_string(r.result.final_health), r.result.resets);
  return r;
}

// GPS over a whole run: the hand-over happened, the filter took (nearly) every later fix, no health reset.
void expect_gps_run(const HallRun& r, double duration_s) {
  ASSERT_GT(r.handover_s, 0.0) << "the fixes never handed over to the filter";
  const double fixes_after = 5.0 * (duration_s - r.handover_s);
  EXPECT_GT(r.updates, static_cast<int>(0.9 * fixes_after));
  EXPECT_LE(r.rejected, static_cast<int>(0.01 * fixes_after) + 1);  // 99.9 % gate: a few at most
  EXPECT_EQ(r.result.resets, 0);
  EXPECT_EQ(r.result.final_health, slam::Health::Ok);
}

// 20 s: the fixes' spread does not yet give the yaw to the 3 deg of the hand-over (at ~34 s in the 45 s
// run), so this checks the rigid least-squares moves before it: the attitude (yaw from the fixes; the robot's own
// start yaw is ~38 deg off) and the position once the fixes have a spread (after 10 s).
TEST(AbsoluteSensors, GpsShortAlignsTheYawAndBoundsTheError) {
  const HallRun r = run_hall({20.0, true, false, true}, 10.0);
  EXPECT_LE(r.max_err_m, 0.3);
  EXPECT_LE(r.final_err_m, 0.2);
  EXPECT_LE(r.att_err_deg, 5.0);
  EXPECT_EQ(r.result.resets, 0);
  EXPECT_EQ(r.result.final_health, slam::Health::Ok);
}

// Measured: ATE 0.246 m (the 34 s before the hand-over dominate), final error 0.07 m, no reset.
TEST(AbsoluteSensorsSlow, GpsHall45sBoundsTheErrorWithoutAlignment) {
  const HallRun r = run_hall({45.0, true, false, false}, 40.0);
  expect_gps_run(r, 45.0);
  EXPECT_LE(r.ate_m, 0.3);
}

// The acceptance: whole-run ATE without alignment over 5 minutes (measured 0.098 m; hand-over at 33.8 s, 1336 fixes
// applied, 0 rejected, no reset; 8 min on a loaded 2-core machine).
TEST(AbsoluteSensorsSlow, GpsHall5MinutesBoundsTheDriftWithoutAlignment) {
  const HallRun r = run_hall({300.0, true, false, false}, 40.0);
  expect_gps_run(r, 300.0);
  EXPECT_LE(r.ate_m, 0.3);
}

TEST(AbsoluteSensors, MocapShortPutsTheEstimateInTheMocapFrame) {
  const HallRun r = run_hall({4.0, false, true, true}, 2.0);
  ASSERT_GE(r.handover_s, 0.0);
  EXPECT_LT(r.max_err_m, 0.01);
  EXPECT_LT(r.att_err_deg, 0.3);
  EXPECT_GT(r.updates, static_cast<int>(0.9 * 100.0 * (4.0 - r.handover_s - 1.0)));
  EXPECT_EQ(r.result.resets, 0);
}

}  // namespace
}  // namespace rtslam::pipeline
