// Acceptance of the inertial system on recorded sensor data, run as a user would (issue "Inertial SLAM that holds on
// real IMU data"): the estimator sees a folder holding sensors and calibration only; the reference trajectory lies
// elsewhere and is read by the evaluation alone.
//  - Recorded-IMU V1_01 (config/sim/euroc-v101-recorded.yaml: the recorded states followed exactly, the RECORDED
//    ADIS16448 stream, cam0 rendered at the recorded times), the whole 145 s flight with config/euroc_mono_imu.yaml:
//    SE(3) ATE <= 2.5 cm, scale error <= 1 %, pose NEES inside its 99 % band >= 90 % of the time.
//  - Twenty starts at different instants of that flight (the first at the vibrating rest, the others in motion):
//    SE(3) ATE over the last 80 % of each run <= 3 cm.
//  - Ten seeds of the high-dynamic sequence (EuRoC cam0 and ADIS16448 models, 400 deg/s, 3 g), each started in motion
//    (30 s in, the extreme phase): SE(3) ATE <= 1 cm.
//  - The monocular preset (config/euroc_mono.yaml) on the same recorded V1_01 motion: >= 12 matches in >= 95 % of the
//    frames, Sim(3) ATE <= 1 % of the path.
// The rendered folder is written once to RTSLAM_TEST_DATA (default: the build folder's test-data/) and reused.
// Label slow: `ctest --test-dir build -L slow -R inertial_acceptance` (docs/testing.md); the figures are printed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "rtslam/eval/metrics.hpp"
#include "rtslam/eval/run_eval.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/trajectory_io.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/sim/simulation.hpp"

namespace rtslam::pipeline {
namespace {

namespace fs = std::filesystem;

const std::string kStatic = RTSLAM_SOURCE_DIR "/../shared/datasets/euroc-v101-static";

fs::path test_data_dir() {
  if (const char* d = std::getenv("RTSLAM_TEST_DATA")) return d;
  return fs::path(RTSLAM_BINARY_DIR) / "test-data";
}

// The recorded-IMU V1_01 flight rendered once, cam0 and cam1 (ground truth beside, not in mav0/).
fs::path recorded_v101() {
  const fs::path dir = test_data_dir() / "euroc-v101-recorded";
  if (fs::exists(dir / "groundtruth" / "state.csv") && fs::exists(dir / "mav0" / "cam0" / "data.csv") &&
      fs::exists(dir / "mav0" / "cam1" / "data.csv")) {
    return dir;
  }
  fs::remove_all(dir);
  sim::SimConfig sc = sim::SimConfig::load(RTSLAM_SOURCE_DIR "/config/sim/euroc-v101-recorded.yaml");
  sc.stereo = true;
  sim::Simulation::create(sc)->write_euroc(dir.string(), true);
  return dir;
}

struct FolderRun {
  ImageSlamResult result;
  eval::RunAccuracy accuracy;
};

FolderRun run_folder(const fs::path& dir, const ImageSlamOptions& o, double start_at_s = 0.0, double duration_s = 0.0) {
  io::DatasetOptions dopt;
  dopt.use_imu = o.robot == "inertial";
  dopt.cameras = o.camera_indices();
  dopt.start_offset_s = start_at_s;
  dopt.duration_s = duration_s;
  io::Dataset ds = io::open_dataset("euroc:" + dir.string(), dopt);
  EXPECT_FALSE(ds.ground_truth.has_value()) << "the run must not see the ground truth";
  FolderRun r;
  r.result = run_image_slam(ds, o.on_selected_cameras());
  const Trajectory gt = io::read_trajectory((dir / "groundtruth" / "state.csv").string());
  r.accuracy = eval::evaluate_accuracy(r.result.estimate, gt, o.robot == "inertial" || r.result.cameras > 1);
  return r;
}

// SE(3) ATE (m) over the last 80 % of an estimate.
double ate_last_80(const Trajectory& est, const Trajectory& gt) {
  Trajectory tail = est;
  tail.poses.erase(tail.poses.begin(), tail.poses.begin() + static_cast<std::ptrdiff_t>(est.poses.size() / 5));
  eval::EvalOptions eo;
  eo.align = eval::Alignment::Se3;
  eo.with_rpe = false;
  eo.association.interpolate = true;
  return eval::evaluate(tail, gt, eo).ate.trans_m.rmse;
}

ImageSlamOptions euroc_imu_preset() { return load_image_slam_config(RTSLAM_SOURCE_DIR "/config/euroc_mono_imu.yaml"); }

TEST(InertialAcceptance, RecordedV101WholeFlight) {
  if (!fs::exists(kStatic)) GTEST_SKIP() << "dataset " << kStatic << " not found";
  const FolderRun r = run_folder(recorded_v101(), euroc_imu_preset());
  const auto& a = r.accuracy;
  std::printf(
      "recorded V1_01, euroc_mono_imu: %zu frames, SE(3) ATE %.2f cm over %.1f m (max %.2f cm), scale error "
      "%.2f %%, RPE per 10 m %.2f cm, NEES mean %.2f with %.1f %% inside the 99 %% band; %s\n",
      r.result.estimate.poses.size(), 100 * a.ate.ate.trans_m.rmse, a.ate.path_length_m, 100 * a.ate.ate.trans_m.max,
      100 * a.scale_error, a.rpe_10m ? 100 * a.rpe_10m->trans_m.rmse : 0.0, a.nees ? a.nees->mean : 0.0,
      a.nees ? 100 * a.nees->fraction_in_band : 0.0, r.result.inertial_start.c_str());
  EXPECT_LE(a.ate.ate.trans_m.rmse, 0.025);
  EXPECT_LE(a.scale_error, 0.01);
  ASSERT_TRUE(a.nees.has_value());
  EXPECT_GE(a.nees->fraction_in_band, 0.90);
}

TEST(InertialAcceptance, RecordedV101TwentyStarts) {
  if (!fs::exists(kStatic)) GTEST_SKIP() << "dataset " << kStatic << " not found";
  const fs::path dir = recorded_v101();
  const Trajectory gt = io::read_trajectory((dir / "groundtruth" / "state.csv").string());
  int passed = 0;
  for (int k = 0; k < 20; ++k) {
    const double start = 6.5 * k;  // 0 (vibrating rest) .. 123.5 s
    const FolderRun r = run_folder(dir, euroc_imu_preset(), start);
    const double ate = ate_last_80(r.result.estimate, gt);
    passed += ate <= 0.03 ? 1 : 0;
    std::printf("start at %6.1f s: %4zu frames, SE(3) ATE over the last 80 %% %.2f cm, %d reset(s); %s\n", start,
                r.result.estimate.poses.size(), 100 * ate, r.result.resets, r.result.inertial_start.c_str());
    EXPECT_LE(ate, 0.03) << "start at " << start << " s";
  }
  std::printf("%d of 20 starts within 3 cm\n", passed);
}

TEST(InertialAcceptance, HighDynamicTenSeedsStartedInMotion) {
  for (std::uint64_t seed = 1; seed <= 10; ++seed) {
    ImageSlamOptions o = euroc_imu_preset();
    o.seed = seed;
    o.sim_preset = "high-dynamic";
    o.sim_duration_s = 45.0;
    io::Dataset ds = make_sim_dataset(o);
    const Trajectory gt = *ds.ground_truth;
    ds.ground_truth.reset();
    ds.source = std::make_unique<io::WindowSource>(std::move(ds.source), 30.0, 0.0);
    const ImageSlamResult r = run_image_slam(ds, o);
    const eval::RunAccuracy a = eval::evaluate_accuracy(r.estimate, gt, true);
    std::printf(
        "high-dynamic seed %2llu from 30 s: %zu frames, SE(3) ATE %.2f cm (max %.2f cm), scale error %.2f %%; "
        "%s\n",
        static_cast<unsigned long long>(seed), r.estimate.poses.size(), 100 * a.ate.ate.trans_m.rmse,
        100 * a.ate.ate.trans_m.max, 100 * a.scale_error, r.inertial_start.c_str());
    EXPECT_LE(a.ate.ate.trans_m.rmse, 0.01) << "seed " << seed;
  }
}

TEST(InertialAcceptance, MonocularPresetOnRecordedV101Motion) {
  if (!fs::exists(kStatic)) GTEST_SKIP() << "dataset " << kStatic << " not found";
  const FolderRun r = run_folder(recorded_v101(), load_image_slam_config(RTSLAM_SOURCE_DIR "/config/euroc_mono.yaml"));
  const auto& frames = r.result.frames;
  const auto good =
      std::count_if(frames.begin(), frames.end(), [](const slam::FrameStats& f) { return f.matched >= 12; });
  const double frac = static_cast<double>(good) / static_cast<double>(frames.size());
  const double pct = 100.0 * r.accuracy.ate.ate.trans_m.rmse / r.accuracy.ate.path_length_m;
  std::printf(
      "recorded V1_01, euroc_mono: %zu frames, %.1f %% with >= 12 matches, Sim(3) ATE %.2f cm = %.2f %% of the "
      "%.1f m path, scale %.3f, %d reset(s)\n",
      frames.size(), 100 * frac, 100 * r.accuracy.ate.ate.trans_m.rmse, pct, r.accuracy.ate.path_length_m,
      r.accuracy.ate.sim3_scale, r.result.resets);
  EXPECT_GE(frac, 0.95);
  EXPECT_LE(pct, 1.0);
}

// Stereo on the same flight (issue "One frame loop in the System ... several cameras"): without the IMU the baseline
// gives the scale (SE(3) ATE <= 1 % of the path), and stereo-inertial beats mono-inertial.
TEST(InertialAcceptance, StereoOnRecordedV101) {
  if (!fs::exists(kStatic)) GTEST_SKIP() << "dataset " << kStatic << " not found";
  const FolderRun cv = run_folder(recorded_v101(), load_image_slam_config(RTSLAM_SOURCE_DIR "/config/euroc_stereo.yaml"));
  const FolderRun vi =
      run_folder(recorded_v101(), load_image_slam_config(RTSLAM_SOURCE_DIR "/config/euroc_stereo_imu.yaml"));
  const FolderRun mono = run_folder(recorded_v101(), euroc_imu_preset());
  const auto line = [](const char* name, const FolderRun& r) {
    std::printf("recorded V1_01, %s: %zu frames, SE(3) ATE %.2f cm = %.3f %% of the %.1f m path, scale error %.2f %%, "
                "%d reset(s)\n",
                name, r.result.estimate.poses.size(), 100 * r.accuracy.ate.ate.trans_m.rmse,
                100 * r.accuracy.ate.ate.trans_m.rmse / r.accuracy.ate.path_length_m, r.accuracy.ate.path_length_m,
                100 * r.accuracy.scale_error, r.result.resets);
  };
  line("euroc_stereo (constant velocity, no IMU)", cv);
  line("euroc_stereo_imu", vi);
  line("euroc_mono_imu", mono);
  EXPECT_EQ(cv.result.cameras, 2);
  EXPECT_LE(cv.accuracy.ate.ate.trans_m.rmse, 0.01 * cv.accuracy.ate.path_length_m);
  EXPECT_LT(vi.accuracy.ate.ate.trans_m.rmse, mono.accuracy.ate.ate.trans_m.rmse);
}

}  // namespace
}  // namespace rtslam::pipeline
