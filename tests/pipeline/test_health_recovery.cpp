// The health monitor's recovery on the inertial preset (config/euroc_mono_imu.yaml) over the simulated hand-held
// sequence, with faults injected into the stream:
//  - a corrupted IMU burst (0.2 s of gyro and accelerometer readings off by several rad/s and m/s²): the filter
//    diverges, the monitor says so (frames.csv health column), the robot and map are re-initialized, and the system
//    tracks again within 1 s of the re-initialization, to the end of the run;
//  - a 2 s blackout of images (the IMU goes on): the gap is noted, and within 1 s of the images' return the system
//    tracks again (by itself or after a re-initialization), to the end of the run.
// "Tracks" = at least health/min_updated corrections in every frame.
// And without injected faults, a run whose matches one-point RANSAC stops explaining with one motion (the `ground`
// preset, seed 8): the consensus verdict, and none with it off.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <variant>

#include "rtslam/pipeline/image_slam.hpp"

namespace rtslam::pipeline {
namespace {

class FaultInjector final : public io::Source {
 public:
  FaultInjector(std::unique_ptr<io::Source> inner, TimeNs from, TimeNs to, bool imu_burst)
      : inner_(std::move(inner)), from_(from), to_(to), imu_burst_(imu_burst) {}
  std::optional<io::Measurement> next() override {
    while (auto m = inner_->next()) {
      const TimeNs t = io::time_of(*m);
      if (t < from_ || t > to_) return m;
      if (auto* imu = std::get_if<io::ImuSample>(&*m)) {
        if (imu_burst_) {
          imu->gyro += Eigen::Vector3d(3.0, -2.0, 4.0);
          imu->accel += Eigen::Vector3d(20.0, -15.0, 10.0);
          ++corrupted_;
        }
        return m;
      }
      if (imu_burst_) return m;
      ++dropped_;  // blackout: the image never arrives
    }
    return std::nullopt;
  }
  const io::SourceStats& stats() const override { return inner_->stats(); }
  int corrupted_ = 0, dropped_ = 0;

 private:
  std::unique_ptr<io::Source> inner_;
  TimeNs from_, to_;
  bool imu_burst_;
};

struct RecoveryOutcome {
  ImageSlamResult r;
  TimeNs fault_from = 0, fault_to = 0;
};

RecoveryOutcome run_with_fault(bool imu_burst) {
  ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/euroc_mono_imu.yaml");
  o.sim_preset = "handheld";
  o.sim_duration_s = 12.0;
  io::Dataset ds = make_sim_dataset(o);
  const TimeNs t0 = ds.ground_truth->poses.front().t;
  RecoveryOutcome out;
  out.fault_from = t0 + from_seconds(6.0);
  out.fault_to = t0 + from_seconds(imu_burst ? 6.2 : 8.0);
  auto injector = std::make_unique<FaultInjector>(std::move(ds.source), out.fault_from, out.fault_to, imu_burst);
  FaultInjector& inj = *injector;
  ds.source = std::move(injector);
  out.r = run_image_slam(ds, o);
  EXPECT_GT(imu_burst ? inj.corrupted_ : inj.dropped_, 0);
  return out;
}

// The first time from which every frame to the end tracks (>= min_updated corrections); -1 if the last does not.
TimeNs tracking_since(const ImageSlamResult& r, int min_updated) {
  TimeNs since = -1;
  for (const auto& f : r.frames) {
    if (f.updated >= min_updated) {
      if (since < 0) since = f.t;
    } else {
      since = -1;
    }
  }
  return since;
}

TEST(HealthRecovery, ACorruptedImuBurstIsDetectedAndTrackingResumesWithinOneSecond) {
  const RecoveryOutcome o = run_with_fault(true);
  const auto& frames = o.r.frames;
  const auto reset = std::find_if(frames.begin(), frames.end(), [](const slam::FrameStats& f) { return f.reset; });
  ASSERT_NE(reset, frames.end()) << "the divergence was not detected";
  const int verdict = reset->health;
  EXPECT_NE(verdict, 0);
  EXPECT_GE(reset->t, o.fault_from);
  const TimeNs since = tracking_since(o.r, 3);
  std::printf("IMU burst [%.1f, %.1f] s: %s verdict at %.2f s, re-initialized; tracking (>= 3 corrections per frame) "
              "from %.2f s to the end; %d reset(s), %d lost / %d diverged frames\n",
              to_seconds(o.fault_from - frames.front().t) , to_seconds(o.fault_to - frames.front().t),
              verdict == 1 ? "lost" : "diverged", to_seconds(reset->t - frames.front().t),
              to_seconds(since - frames.front().t), o.r.resets, o.r.frames_lost, o.r.frames_diverged);
  ASSERT_GE(since, 0) << "does not track at the end";
  EXPECT_LE(to_seconds(since - reset->t), 1.0);
  EXPECT_EQ(o.r.final_health, slam::Health::Ok);
}

TEST(HealthRecovery, ATwoSecondImageBlackoutIsNotedAndTrackingResumesWithinOneSecond) {
  const RecoveryOutcome o = run_with_fault(false);
  const auto& frames = o.r.frames;
  EXPECT_EQ(o.r.frame_gaps, 1);
  const auto back = std::find_if(frames.begin(), frames.end(), [&](const slam::FrameStats& f) { return f.t > o.fault_to; });
  ASSERT_NE(back, frames.end());
  const TimeNs since = tracking_since(o.r, 3);
  std::printf("image blackout [%.1f, %.1f] s: images back at %.2f s; tracking from %.2f s to the end; %d reset(s)\n",
              to_seconds(o.fault_from - frames.front().t), to_seconds(o.fault_to - frames.front().t),
              to_seconds(back->t - frames.front().t), to_seconds(since - frames.front().t), o.r.resets);
  ASSERT_GE(since, 0) << "does not track at the end";
  EXPECT_LE(to_seconds(since - back->t), 1.0);
  EXPECT_EQ(o.r.final_health, slam::Health::Ok);
}

// The simulator's `ground` preset, seed 8, odometry robot: between 3 and 4.5 s the filter turns its attitude by 13°
// while every match passes its gate and the NIS per dof stays near 1; only one-point RANSAC's support collapses
// (docs/configuration.md "health"). The consensus verdict catches it; with it off, nothing does. A regression check
// on one recorded failure of the simulation: a change to the front end or the filter may make this failure go away
// (then find another; tests/slam/test_health.cpp checks the verdict's logic on hand-made frames).
TEST(HealthRecovery, MatchesThatNoSingleMotionExplainsAreCaughtAndTheRunReinitializes) {
  const auto run = [](double min_consensus) {
    ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/sim_mono.yaml");
    o.sim_preset = "ground";
    o.seed = 8;
    o.robot = "odometry";
    o.sim_duration_s = 20.0;  // the 20 s sequence (the preset's laps depend on the duration), its first 5 s
    o.health.min_consensus = min_consensus;
    io::Dataset ds = make_sim_dataset(o);
    ds.source = std::make_unique<io::WindowSource>(std::move(ds.source), 0.0, 5.0);
    return run_image_slam(ds, o);
  };
  const ImageSlamResult on = run(slam::HealthOptions{}.min_consensus);
  const TimeNs t0 = on.frames.front().t;
  TimeNs lost_at = -1;
  for (const auto& f : on.frames) {
    if (f.health == static_cast<int>(slam::Health::Lost) && lost_at < 0) lost_at = f.t;
  }
  ASSERT_GE(lost_at, 0) << "no verdict";
  EXPECT_GT(to_seconds(lost_at - t0), 2.0);  // not while the map and the motion agree
  EXPECT_EQ(on.resets, 1);
  std::printf("consensus verdict at %.2f s of the run\n", to_seconds(lost_at - t0));
  const ImageSlamResult off = run(0.0);
  EXPECT_EQ(off.frames_lost + off.frames_diverged, 0);
}

}  // namespace
}  // namespace rtslam::pipeline
