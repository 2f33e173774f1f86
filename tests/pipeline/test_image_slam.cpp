// Monocular image SLAM on real data: the EuRoC V1_01 standstill (95 frames of cam0, the MAV at rest on the floor)
// with config/euroc_mono.yaml, and the MonoSLAM hand-held sequence with its known target and
// config/monoslam_davison.yaml.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <variant>

#include <Eigen/Eigenvalues>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/pipeline/default_config.hpp"
#include "rtslam/pipeline/image_slam.hpp"

namespace rtslam::pipeline {
namespace {

const std::string kEuroc = RTSLAM_SOURCE_DIR "/../shared/datasets/euroc-v101-static";
const std::string kConfig = RTSLAM_SOURCE_DIR "/config/euroc_mono.yaml";

ImageSlamResult run_euroc(const ImageSlamOptions& o) {
  io::DatasetOptions dopt;
  dopt.use_imu = false;
  io::Dataset ds = io::open_dataset("euroc:" + kEuroc, dopt);
  return run_image_slam(ds, o);
}

double position_sigma(const StampedPose& p) {
  const Eigen::Matrix3d P = p.cov->topLeftCorner<3, 3>();
  return std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(P).eigenvalues().maxCoeff());
}

TEST(ImageSlam, EurocStandstillStaysPutWhileUncertaintyShrinks) {
  if (!std::filesystem::exists(kEuroc)) GTEST_SKIP() << "dataset " << kEuroc << " not found";
  const ImageSlamOptions o = load_image_slam_config(kConfig);
  const ImageSlamResult r = run_euroc(o);
  ASSERT_EQ(r.estimate.poses.size(), 95u);
  ASSERT_FALSE(r.landmark_depths.empty());
  std::vector<double> depths = r.landmark_depths;
  std::nth_element(depths.begin(), depths.begin() + static_cast<long>(depths.size() / 2), depths.end());
  const double median_depth = depths[depths.size() / 2];
  const StampedPose& first = r.estimate.poses.front();
  double max_trans = 0.0, max_rot = 0.0;
  int min_matched_after_1s = 1000;
  for (size_t k = 0; k < r.estimate.poses.size(); ++k) {
    const StampedPose& p = r.estimate.poses[k];
    max_trans = std::max(max_trans, (p.p_WR - first.p_WR).norm());
    max_rot = std::max(max_rot, p.q_WR.angularDistance(first.q_WR));
    if (p.t - first.t >= 1'000'000'000) min_matched_after_1s = std::min(min_matched_after_1s, r.frames[k].matched);
  }
  RecordProperty("median_depth_m", std::to_string(median_depth));
  std::printf("median depth %.3f m, max translation %.4f m (%.3f %%), max rotation %.4f deg, min matched %d\n",
              median_depth, max_trans, 100.0 * max_trans / median_depth, max_rot * 180.0 / M_PI,
              min_matched_after_1s);
  EXPECT_GE(min_matched_after_1s, 15);
  EXPECT_LT(max_trans, 0.02 * median_depth);
  EXPECT_LT(max_rot * 180.0 / M_PI, 0.5);
  // The pose uncertainty shrinks once the map is built: after 1 s (20 frames) it is larger than at the end. A filter
  // that never corrects would see it grow like t^3 under the constant-velocity model.
  const double sigma_1s = position_sigma(r.estimate.poses[20]);
  const double sigma_end = position_sigma(r.estimate.poses.back());
  std::printf("position sigma: %.5f m at 1 s, %.5f m at the end\n", sigma_1s, sigma_end);
  EXPECT_LT(sigma_end, sigma_1s);
  EXPECT_LT(sigma_end, 0.01 * median_depth);
  // The per-stage times (frames.csv) are measured, non-negative, and add up to at most the frame's total.
  for (const slam::FrameStats& f : r.frames) {
    for (double t : {f.time_predict_ms, f.time_match_ms, f.time_ransac_ms, f.time_update_ms, f.time_init_ms,
                     f.time_map_ms})
      EXPECT_GE(t, 0.0);
    EXPECT_LE(f.time_predict_ms + f.time_match_ms + f.time_ransac_ms + f.time_update_ms + f.time_init_ms +
                  f.time_map_ms,
              f.time_total_ms * (1.0 + 1e-9) + 1e-6);
    if (f.searched > 0) {
      EXPECT_GT(f.time_match_ms, 0.0);
    }
    if (f.ransac_inliers > 0) {
      EXPECT_GT(f.time_ransac_ms, 0.0);
    }
  }
}

TEST(ImageSlam, SameRunTwiceGivesIdenticalTrajectories) {
  if (!std::filesystem::exists(kEuroc)) GTEST_SKIP() << "dataset " << kEuroc << " not found";
  ImageSlamOptions o = load_image_slam_config(kConfig);
  o.max_frames = 30;
  const ImageSlamResult a = run_euroc(o);
  const ImageSlamResult b = run_euroc(o);
  ASSERT_EQ(a.estimate.poses.size(), 30u);
  ASSERT_EQ(a.estimate.poses.size(), b.estimate.poses.size());
  for (size_t k = 0; k < a.estimate.poses.size(); ++k) {
    EXPECT_EQ(a.estimate.poses[k].p_WR, b.estimate.poses[k].p_WR);
    EXPECT_EQ(a.estimate.poses[k].q_WR.coeffs(), b.estimate.poses[k].q_WR.coeffs());
  }
  EXPECT_EQ(a.landmarks_created, b.landmarks_created);
  EXPECT_GT(a.landmarks_created, 15);
}

// An IMU stream that stops before the camera's: the inertial run cannot start and says why (not "no image").
class ImuEndsAt final : public io::Source {
 public:
  ImuEndsAt(std::unique_ptr<io::Source> inner, TimeNs end) : inner_(std::move(inner)), end_(end) {}
  std::optional<io::Measurement> next() override {
    while (auto m = inner_->next()) {
      if (const auto* imu = std::get_if<io::ImuSample>(&*m); imu && imu->t > end_) continue;
      return m;
    }
    return std::nullopt;
  }
  const io::SourceStats& stats() const override { return inner_->stats(); }

 private:
  std::unique_ptr<io::Source> inner_;
  TimeNs end_;
};

TEST(ImageSlam, InertialRunWhoseImuEndsBeforeTheImagesSaysSo) {
  if (!std::filesystem::exists(kEuroc)) GTEST_SKIP() << "dataset " << kEuroc << " not found";
  const ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/euroc_mono_imu.yaml");
  io::DatasetOptions dopt;
  dopt.use_imu = true;
  io::Dataset ds = io::open_dataset("euroc:" + kEuroc, dopt);
  const TimeNs first_image = 1403715273262142976;  // cam0's first image
  ds.source = std::make_unique<ImuEndsAt>(std::move(ds.source), first_image + 200'000'000);
  try {
    run_image_slam(ds, o);
    FAIL() << "the run started without IMU data over its images";
  } catch (const DataError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("the IMU stream ends before the images"), std::string::npos) << what;
    EXPECT_NE(what.find("1403715273.462"), std::string::npos) << "the last IMU time: " << what;
  }
}

// Images that turn blank (one grey level) from `from` on: the camera covered.
class BlankFrom final : public io::Source {
 public:
  BlankFrom(std::unique_ptr<io::Source> inner, TimeNs from) : inner_(std::move(inner)), from_(from) {}
  std::optional<io::Measurement> next() override {
    auto m = inner_->next();
    if (m) {
      if (auto* img = std::get_if<io::ImageFrame>(&*m); img && img->t >= from_) img->image.setTo(128);
    }
    return m;
  }
  const io::SourceStats& stats() const override { return inner_->stats(); }

 private:
  std::unique_ptr<io::Source> inner_;
  TimeNs from_;
};

// The count of created landmarks is every landmark the run added, also when none is left at the end (the camera
// covered for the last 2 s: the map is emptied and re-initialized, and no new landmark can be made).
TEST(ImageSlam, CreatedLandmarksCountThoseRemovedBeforeTheEnd) {
  if (!std::filesystem::exists(kEuroc)) GTEST_SKIP() << "dataset " << kEuroc << " not found";
  const ImageSlamOptions o = load_image_slam_config(kConfig);
  io::DatasetOptions dopt;
  dopt.use_imu = false;
  io::Dataset ds = io::open_dataset("euroc:" + kEuroc, dopt);
  const TimeNs first_image = 1403715273262142976;  // cam0's first image; 95 images at 20 Hz
  ds.source = std::make_unique<BlankFrom>(std::move(ds.source), first_image + 2'700'000'000);
  const ImageSlamResult r = run_image_slam(ds, o);
  ASSERT_EQ(r.frames.size(), 95u);
  EXPECT_EQ(r.landmarks_final, 0);
  int initialized = 0;
  for (const slam::FrameStats& f : r.frames) initialized += f.initialized;
  EXPECT_GT(initialized, 15);
  EXPECT_EQ(r.landmarks_created, initialized);
}

// A run that ends before its robot could start says what the start still needed, or that no image was read.
std::string start_error(const ImageSlamOptions& o, double start_offset_s, double duration_s) {
  io::DatasetOptions dopt;
  dopt.use_imu = true;
  dopt.start_offset_s = start_offset_s;
  dopt.duration_s = duration_s;
  io::Dataset ds = io::open_dataset("euroc:" + kEuroc, dopt);
  try {
    run_image_slam(ds, o);
  } catch (const DataError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(ImageSlam, ARunEndingBeforeTheStartSaysWhatTheStartNeeded) {
  if (!std::filesystem::exists(kEuroc)) GTEST_SKIP() << "dataset " << kEuroc << " not found";
  ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/euroc_mono_imu.yaml");
  // 0.3 s of input: 7 images, fewer than the visual-inertial start's window of 0.4 s.
  std::string what = start_error(o, 0.0, 0.3);
  EXPECT_NE(what.find("did not start over its 7 image(s) of camera cam0 (1403715273.262 to 1403715273.562 s, the IMU"),
            std::string::npos) << what;
  EXPECT_NE(what.find("0.40 s of images for the visual-inertial start (imu/vi_init/window"), std::string::npos)
      << what;
  // Without the visual-inertial start: the IMU starts with the first image, and 0.5 s of it must precede one.
  o.imu.vi_init.enabled = false;
  what = start_error(o, 0.0, 0.3);
  EXPECT_NE(what.find("0.50 s of IMU data before an image (imu/init_window; the IMU starts at 1403715273.262 s)"),
            std::string::npos) << what;
  // A window past the images (the IMU goes on for the whole flight, the images for 4.7 s): none read.
  what = start_error(o, 100.0, 0.0);
  EXPECT_NE(what.find("has no image of camera cam0 (in the part of it read"), std::string::npos) << what;
}

const std::string kMonoslam = RTSLAM_SOURCE_DIR "/../shared/datasets/monoslam-davison";


ImageSlamResult run_monoslam(int max_frames, const std::string& overlay_path, int overlay_frame) {
  ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/monoslam_davison.yaml");
  o.known_landmarks = kMonoslam + "/init";
  o.max_frames = max_frames;
  o.overlay_frame = overlay_frame;
  o.overlay_path = overlay_path;
  io::DatasetOptions dopt;
  dopt.use_imu = false;
  dopt.rate_hz = o.rate_hz;
  io::Dataset ds = io::open_dataset("images:" + kMonoslam, dopt);
  return run_image_slam(ds, o);
}

// The whole hand-held sequence (1000 frames, 33 s) with the known-target initialization: the 4 known corners are
// found in frame 0, every frame is tracked with >= 12 matched landmarks in >= 95 % of them, the position stays
// certain (sigma < 5 cm) and smooth (no jump > 10 cm between frames); the overlay of frame 500 is written.
TEST(ImageSlam, MonoslamKnownTargetTracksTheWholeSequence) {
  if (!std::filesystem::exists(kMonoslam)) GTEST_SKIP() << "dataset " << kMonoslam << " not found";
  constexpr int kFrames = 1000;
  const std::string overlay =
      (std::filesystem::temp_directory_path() / "rtslam_test_monoslam_overlay_00500.png").string();
  std::filesystem::remove(overlay);
  const ImageSlamResult r = run_monoslam(kFrames, overlay, 500);
  ASSERT_EQ(r.estimate.poses.size(), static_cast<size_t>(kFrames));
  EXPECT_EQ(r.known_landmarks, 4);
  EXPECT_GE(r.frames[0].matched, 4);
  EXPECT_GE(r.frames[0].updated, 4);
  int good = 0;
  double max_sigma = 0.0, max_jump = 0.0;
  for (size_t k = 0; k < r.estimate.poses.size(); ++k) {
    if (r.frames[k].matched >= 12) ++good;
    max_sigma = std::max(max_sigma, position_sigma(r.estimate.poses[k]));
    if (k > 0) max_jump = std::max(max_jump, (r.estimate.poses[k].p_WR - r.estimate.poses[k - 1].p_WR).norm());
  }
  std::printf("monoslam %d frames: %d with >= 12 matched, max position sigma %.4f m, max jump %.4f m\n", kFrames,
              good, max_sigma, max_jump);
  EXPECT_GE(good, static_cast<int>(0.95 * kFrames));
  EXPECT_LT(max_sigma, 0.05);
  EXPECT_LT(max_jump, 0.10);
  EXPECT_TRUE(std::filesystem::exists(overlay));
  EXPECT_GT(std::filesystem::file_size(overlay), 10000u);
  std::filesystem::remove(overlay);
}

TEST(ImageSlamConfig, PresetRoundTripsAndRejectsUnknownKeys) {
  const ImageSlamOptions o = load_image_slam_config(kConfig);
  ImageSlamOptions back;
  apply_image_slam_config(to_yaml(o), "round trip", back);
  EXPECT_EQ(YAML::Dump(to_yaml(back)), YAML::Dump(to_yaml(o)));
  ImageSlamOptions bad;
  EXPECT_THROW(apply_image_slam_config(YAML::Load("{search: {sigma_pix: 2}}"), "bad.yaml", bad), ConfigError);
  EXPECT_THROW(apply_image_slam_config(YAML::Load("{map_manager: {policy: forever}}"), "bad.yaml", bad), ConfigError);
}

// `rtslam run` on the simulator without --config uses config/sim_mono.yaml, compiled in.
TEST(ImageSlamConfig, BuiltInSimulatorDefaultIsTheSimMonoPreset) {
  const ImageSlamOptions file = load_image_slam_config(RTSLAM_SOURCE_DIR "/config/sim_mono.yaml");
  EXPECT_EQ(YAML::Dump(to_yaml(default_sim_options())), YAML::Dump(to_yaml(file)));
  EXPECT_NE(YAML::Dump(to_yaml(default_sim_options())), YAML::Dump(to_yaml(ImageSlamOptions{})));
}

}  // namespace
}  // namespace rtslam::pipeline
