// Several cameras on one robot (slam/cameras, issue "One frame loop in the System ... several cameras"): the
// simulator's stereo rig (EuRoC cam0 + cam1, 11 cm baseline) with config/sim_stereo.yaml, constant velocity and no
// IMU: the landmarks are shared by both cameras, so the scale is known from the baseline (SE(3) alignment, scale
// error); both cameras match in every frame and one frame is reported per image time. And the real EuRoC standstill
// in stereo. The recorded V1_01 flight in stereo is part of the slow acceptance (test_inertial_acceptance).
#include <gtest/gtest.h>

#include <filesystem>
#include <set>

#include "rtslam/eval/run_eval.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/pipeline/image_slam.hpp"

namespace rtslam::pipeline {
namespace {

const std::string kStereoEuroc = RTSLAM_SOURCE_DIR "/../shared/datasets/euroc-v101-static";

TEST(Stereo, SimulatedStereoKnowsTheScaleWithoutAnImu) {
  ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/sim_stereo.yaml");
  o.sim_duration_s = 8.0;
  io::Dataset ds = make_sim_dataset(o);
  ASSERT_EQ(ds.rig.cameras.size(), 2u);
  ASSERT_TRUE(ds.ground_truth.has_value());
  int frames_with_both = 0, observed = 0;
  std::set<TimeNs> times;
  const auto observer = [&](const ImageSlamFrame& f) {
    ++observed;
    times.insert(f.t);
    // The observer sees each time once, after its last camera (cam1): its matches are cam1's; the frame's stats
    // sum both cameras.
    int cam1_matched = 0;
    for (const auto& m : *f.matches) cam1_matched += m.matched ? 1 : 0;
    if (cam1_matched >= 5 && f.stats->matched > cam1_matched) ++frames_with_both;
  };
  const ImageSlamResult r = run_image_slam(ds, o, {}, observer);
  EXPECT_EQ(r.cameras, 2);
  ASSERT_EQ(r.estimate.poses.size(), 161u);  // 8 s at 20 Hz: one pose per image time, not per image
  EXPECT_EQ(r.frames.size(), r.estimate.poses.size());
  EXPECT_EQ(observed, static_cast<int>(r.frames.size()));
  EXPECT_EQ(times.size(), r.frames.size());
  EXPECT_GE(frames_with_both, 150);
  const eval::RunAccuracy a = eval::evaluate_accuracy(r.estimate, *ds.ground_truth, /*metric_scale=*/true);
  std::printf("sim stereo, 8 s: SE(3) ATE %.2f mm over %.2f m (%.3f %%), scale error %.2f %%, %d of %zu frames "
              "matched in both cameras\n",
              1e3 * a.ate.ate.trans_m.rmse, a.ate.path_length_m, 100 * a.ate.ate.trans_m.rmse / a.ate.path_length_m,
              100 * a.scale_error, frames_with_both, r.frames.size());
  EXPECT_LE(a.ate.ate.trans_m.rmse, 0.01 * a.ate.path_length_m);
  EXPECT_LE(a.scale_error, 0.02);
  EXPECT_EQ(r.final_health, slam::Health::Ok);
}

TEST(Stereo, EurocStandstillInStereo) {
  if (!std::filesystem::exists(kStereoEuroc)) GTEST_SKIP() << "dataset " << kStereoEuroc << " not found";
  ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/euroc_stereo.yaml");
  io::DatasetOptions dopt;
  dopt.use_imu = false;
  dopt.cameras = o.camera_indices();
  dopt.bad_input = io::BadInputPolicy::Skip;  // cam1/data.csv lists 4 images its folder does not hold
  io::Dataset ds = io::open_dataset("euroc:" + kStereoEuroc, dopt);
  const ImageSlamResult r = run_image_slam(ds, o.on_selected_cameras());
  ASSERT_EQ(r.estimate.poses.size(), 95u);
  double max_dp = 0.0;
  for (const auto& p : r.estimate.poses) max_dp = std::max(max_dp, (p.p_WR - r.estimate.poses.front().p_WR).norm());
  std::printf("EuRoC standstill in stereo: %zu frames, max displacement %.2f mm, %d landmarks\n",
              r.estimate.poses.size(), 1e3 * max_dp, r.landmarks_final);
  EXPECT_LT(max_dp, 0.01);
  EXPECT_GE(r.frames.back().matched, 30);
}

}  // namespace
}  // namespace rtslam::pipeline
