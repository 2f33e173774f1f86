// The overlay drawing (draw_overlay) and its writers: ellipse pixels for a known S, colours by a match's fate,
// search regions, measurements, new landmarks, the init grid; one PNG per frame with its index; the video writer.
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*
#include <opencv2/videoio.hpp>  // cv::CAP_*

#include "rtslam/core/error.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/viz/overlay.hpp"
#include "rtslam/viz/replay.hpp"
#include "viz/viz_test_utils.hpp"
#include "support/temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
using namespace rtslam;
using namespace rtslam::viz;
using test::black_at;
using test::colour_near;

fs::path temp_dir(const std::string& name) { return ::rtslam::support::fresh_temp_dir("test_viz", name); }

OverlayOptions plain() {
  OverlayOptions o;
  o.search_regions = false;
  o.hud = false;
  return o;
}

FrameMatch searched_not_found(const Eigen::Vector2d& h, const Eigen::Matrix2d& S) {
  FrameMatch m;
  m.landmark_id = 3;
  m.h = h;
  m.S = S;
  m.searched = true;
  return m;
}

TEST(Overlay, EllipseOfAKnownCovarianceLiesAtThreeSigma) {
  // σ = 10 px along 30°, 4 px across: the 3σ ellipse has semi-axes 30 and 12 px.
  const double angle = M_PI / 6.0;
  const Eigen::Vector2d h(160.3, 118.7), u(std::cos(angle), std::sin(angle)), v(-std::sin(angle), std::cos(angle));
  FrameReport r = test::blank_report();
  r.matches.push_back(searched_not_found(h, test::covariance(10.0, 4.0, angle)));
  const cv::Mat img = draw_overlay(r, plain());
  ASSERT_EQ(img.type(), CV_8UC3);
  ASSERT_EQ(img.size(), cv::Size(320, 240));
  for (const double s : {-1.0, 1.0}) {
    EXPECT_TRUE(colour_near(img, h + s * 30.0 * u, colour::kFailed)) << "major axis end, side " << s;
    EXPECT_TRUE(colour_near(img, h + s * 12.0 * v, colour::kFailed)) << "minor axis end, side " << s;
    // On the ellipse between the axes: (30 cos φ, 12 sin φ) in the ellipse's frame.
    const double phi = M_PI / 4.0;
    EXPECT_TRUE(colour_near(img, h + s * (30.0 * std::cos(phi) * u + 12.0 * std::sin(phi) * v), colour::kFailed));
    // Inside (2σ) and outside (4σ): nothing drawn.
    EXPECT_TRUE(black_at(img, h + s * 20.0 * u)) << "2σ along the major axis is inside";
    EXPECT_TRUE(black_at(img, h + s * 8.0 * v)) << "2σ along the minor axis is inside";
    EXPECT_TRUE(black_at(img, h + s * 40.0 * u)) << "4σ along the major axis is outside";
    EXPECT_TRUE(black_at(img, h + s * 16.0 * v)) << "4σ along the minor axis is outside";
  }
  // The predicted pixel is marked by a cross.
  EXPECT_TRUE(colour_near(img, h, colour::kFailed));
}

TEST(Overlay, EllipseScalesWithTheOptionsSigma) {
  const Eigen::Vector2d h(160, 120);
  FrameReport r = test::blank_report();
  r.matches.push_back(searched_not_found(h, test::covariance(10.0, 10.0, 0.0)));
  OverlayOptions o = plain();
  o.n_sigma = 2.0;
  const cv::Mat img = draw_overlay(r, o);
  EXPECT_TRUE(colour_near(img, h + Eigen::Vector2d(20, 0), colour::kFailed));
  EXPECT_TRUE(black_at(img, h + Eigen::Vector2d(30, 0)));
}

TEST(Overlay, ColourTellsTheFateOfEachObservation) {
  FrameMatch m;
  EXPECT_EQ(match_colour(m), colour::kPredicted);
  m.searched = true;
  EXPECT_EQ(match_colour(m), colour::kFailed);
  m.matched = true;
  EXPECT_EQ(match_colour(m), colour::kOutlier);
  m.updated = true;
  EXPECT_EQ(match_colour(m), colour::kUpdated);
  m.ransac_inlier = true;
  EXPECT_EQ(match_colour(m), colour::kInlier);
}

TEST(Overlay, MatchesShowTheirMeasurementAndInnovation) {
  const Eigen::Vector2d h(100, 100), z(110, 104);
  FrameReport r = test::blank_report();
  FrameMatch m = searched_not_found(h, test::covariance(8.0, 8.0, 0.0));
  m.matched = m.updated = true;
  m.z = z;
  r.matches.push_back(m);
  const cv::Mat img = draw_overlay(r, plain());
  EXPECT_TRUE(colour_near(img, z + Eigen::Vector2d(3, 0), colour::kUpdated)) << "circle of radius 3 around z";
  EXPECT_TRUE(colour_near(img, 0.5 * (h + z), colour::kUpdated)) << "the innovation segment";
}

TEST(Overlay, SearchRegionsAreTintedOnlyWhenSearched) {
  FrameReport r = test::blank_report();
  r.matches.push_back(searched_not_found({80, 120}, test::covariance(8.0, 8.0, 0.0)));
  FrameMatch skipped = searched_not_found({240, 120}, test::covariance(8.0, 8.0, 0.0));
  skipped.searched = false;
  r.matches.push_back(skipped);
  OverlayOptions o = plain();
  o.search_regions = true;
  const cv::Mat img = draw_overlay(r, o);
  const cv::Vec3b tinted = img.at<cv::Vec3b>(120, 80 + 12);  // inside the searched ellipse (24 px radius)
  EXPECT_GT(tinted[0], 20) << "blue tint of a searched-not-found region";
  EXPECT_LT(tinted[2], 5);
  EXPECT_TRUE(black_at(img, {240 + 12, 120})) << "no tint where nothing was searched";
}

TEST(Overlay, NewLandmarksAndTheInitGridAreDrawn) {
  FrameReport r = test::blank_report();
  LandmarkReport l;
  l.id = 9;
  l.created_now = true;
  l.z0_px = Eigen::Vector2d(200, 60);
  r.landmarks.push_back(l);
  r.grid.push_back(GridCell{Eigen::Vector4d(10, 10, 110, 90), false});
  const cv::Mat img = draw_overlay(r, plain());
  EXPECT_TRUE(colour_near(img, {205, 60}, colour::kNew)) << "circle of radius 5";
  EXPECT_TRUE(colour_near(img, {200, 60}, colour::kNew)) << "cross";
  EXPECT_TRUE(colour_near(img, {60, 10}, colour::kGrid, 1.0)) << "top edge of the cell";
  OverlayOptions o = plain();
  o.grid = false;
  o.new_landmarks = false;
  const cv::Mat none = draw_overlay(r, o);
  EXPECT_EQ(cv::countNonZero(none.reshape(1)), 0);
}

TEST(Overlay, EmptyImageGivesABlackCanvasOfTheCameraSize) {
  FrameReport r = test::blank_report(64, 48);
  r.image.release();
  const cv::Mat img = draw_overlay(r, plain());
  EXPECT_EQ(img.size(), cv::Size(64, 48));
}

TEST(Overlay, NonFiniteCovariancesAreSkippedNotDrawn) {
  FrameReport r = test::blank_report();
  FrameMatch m = searched_not_found({100, 100}, Eigen::Matrix2d::Constant(std::nan("")));
  r.matches.push_back(m);
  const cv::Mat img = draw_overlay(r, plain());
  EXPECT_EQ(cv::countNonZero(img.reshape(1)), 0);
}

TEST(Overlay, OptionsAreValidated) {
  OverlayOptions o;
  o.n_sigma = 0.0;
  EXPECT_THROW(o.validate(), ConfigError);
  o = OverlayOptions{};
  o.search_tint = 1.5;
  EXPECT_THROW(o.validate(), ConfigError);
}

TEST(OverlayWriter, WritesOnePngPerFrameNamedByIndexAndTimeWithAnIndex) {
  const fs::path dir = temp_dir("overlay_writer") / "overlays";
  FrameReport r = test::blank_report();
  r.matches.push_back(searched_not_found({160, 120}, test::covariance(6.0, 3.0, 0.3)));
  {
    OverlayWriter w(dir.string());
    for (int i = 0; i < 3; ++i) {
      r.index = i;
      r.t = 1'000'000'000 + i * 50'000'000;
      w.write(r);
    }
    w.close();
    EXPECT_EQ(w.frames_written(), 3);
  }
  EXPECT_EQ(OverlayWriter::file_name(2, 1'100'000'000), "frame_000002_0000000001100000000.png");
  for (int i = 0; i < 3; ++i) {
    const fs::path png = dir / OverlayWriter::file_name(i, 1'000'000'000 + i * 50'000'000);
    ASSERT_TRUE(fs::exists(png)) << png;
  }
  // Lossless: the PNG is exactly the drawing.
  const cv::Mat back =
      io::codecs::imread((dir / OverlayWriter::file_name(2, 1'100'000'000)).string(), cv::IMREAD_COLOR);
  const cv::Mat drawn = draw_overlay(r);
  ASSERT_EQ(back.size(), drawn.size());
  EXPECT_EQ(cv::norm(back, drawn, cv::NORM_INF), 0.0);
  const auto rows = read_overlay_index((dir / "index.csv").string());
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[1].index, 1);
  EXPECT_EQ(rows[1].t, 1'050'000'000);
  EXPECT_EQ(rows[1].stats.visible, 0) << "counts are the report's";
}

TEST(OverlayWriter, UnwritableFolderNamesThePath) {
  const fs::path file = temp_dir("overlay_writer_bad") / "a_file";
  std::ofstream(file) << "x";
  try {
    OverlayWriter w((file / "sub").string());
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("a_file"), std::string::npos) << e.what();
  }
}

TEST(VideoWriter, WritesEveryFrameToAnAviThatReadsBack) {
  const fs::path file = temp_dir("video") / "run.avi";
  FrameReport r = test::blank_report();
  r.matches.push_back(searched_not_found({160, 120}, test::covariance(6.0, 3.0, 0.3)));
  {
    VideoWriter w(file.string());
    for (int i = 0; i < 6; ++i) {
      r.index = i;
      r.t = 1'000'000'000 + i * 50'000'000;  // 20 Hz
      w.write(r);
    }
    w.close();
    EXPECT_EQ(w.frames_written(), 6);
  }
  const auto cap = io::codecs::open_video(file.string(), cv::CAP_ANY);
  ASSERT_TRUE(cap);
  EXPECT_EQ(static_cast<int>(cap->get(cv::CAP_PROP_FRAME_COUNT)), 6);
  EXPECT_NEAR(cap->get(cv::CAP_PROP_FPS), 20.0, 0.01);
  cv::Mat first;
  ASSERT_TRUE(cap->read(first));
  EXPECT_EQ(first.size(), cv::Size(320, 240));
}

TEST(VideoWriter, CodecComesFromTheExtensionAndUnknownOnesAreRefused) {
  EXPECT_EQ(VideoWriter::fourccs_for("a.AVI").front(), "MJPG");
  EXPECT_EQ(VideoWriter::fourccs_for("a.mp4").front(), "avc1");
  EXPECT_EQ(VideoWriter::fourccs_for("a.mkv").front(), "MJPG");
  EXPECT_EQ(VideoWriter::fourccs_for("a.webm").front(), "VP80");
  try {
    VideoWriter w("/tmp/x.gif");
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(".gif"), std::string::npos) << e.what();
  }
}

}  // namespace
