// rtslam::viz on a real simulated run (config/sim_mono.yaml, 2 s): the reports match the map and the data
// manager's list, `--overlays` writes one PNG per processed frame, and the PNG of a frame shows the 3σ ellipse of
// a known landmark where its S puts it.
#include <filesystem>
#include <optional>
#include <string>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*

#include "rtslam/io/codecs.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/viz/overlay.hpp"
#include "rtslam/viz/report.hpp"
#include "viz/viz_test_utils.hpp"

namespace {

namespace fs = std::filesystem;
using namespace rtslam;

// The image the source gave last (the pipeline's observer does not receive it).
class ImageTap final : public io::Source {
 public:
  explicit ImageTap(std::unique_ptr<io::Source> inner) : inner_(std::move(inner)) {}
  std::optional<io::Measurement> next() override {
    auto m = inner_->next();
    if (m) {
      if (const auto* f = std::get_if<io::ImageFrame>(&*m)) last_ = f->image;
    }
    return m;
  }
  const io::SourceStats& stats() const override { return inner_->stats(); }
  std::optional<std::size_t> image_count() const override { return inner_->image_count(); }
  cv::Mat last_;

 private:
  std::unique_ptr<io::Source> inner_;
};

TEST(PipelineOverlays, OnePngPerProcessedFrameWithTheEllipsesOfAKnownLandmark) {
  pipeline::ImageSlamOptions o = pipeline::load_image_slam_config(std::string(RTSLAM_SOURCE_DIR) + "/config/sim_mono.yaml");
  o.seed = 2;
  o.sim_duration_s = 2.0;
  io::Dataset ds = pipeline::make_sim_dataset(o);
  auto tap_owner = std::make_unique<ImageTap>(std::move(ds.source));
  ImageTap& tap = *tap_owner;
  ds.source = std::move(tap_owner);

  const fs::path dir = fs::temp_directory_path() / "rtslam_test_viz_pipeline" / "overlays";
  fs::remove_all(dir.parent_path());
  viz::OverlayWriter writer(dir.string());
  std::optional<viz::FrameReport> kept;  // the frame with the largest fully visible searched ellipse
  double kept_axis = 0.0;
  int reports = 0;
  const auto observer = [&](const pipeline::ImageSlamFrame& f) {
    viz::FrameReport r = viz::make_report(f, tap.last_);
    ++reports;
    EXPECT_EQ(r.index, f.index);
    EXPECT_EQ(r.landmarks.size(), f.map->landmarks().size());
    EXPECT_EQ(r.matches.size(), f.matches->size());
    EXPECT_EQ(r.image.size(), tap.last_.size());
    EXPECT_EQ(r.image.data, tap.last_.data) << "the report shares the source's image (no pixel copy)";
    const cv::Mat foreign(tap.last_.rows, tap.last_.cols, CV_8UC1, tap.last_.data, tap.last_.step);
    const viz::FrameReport copied = viz::make_report(f, foreign);
    EXPECT_NE(copied.image.data, tap.last_.data) << "an image over foreign memory is copied";
    EXPECT_EQ(cv::norm(copied.image, tap.last_, cv::NORM_INF), 0.0);
    EXPECT_EQ(r.camera.width, tap.last_.cols);
    writer.write(r);
    for (const auto& m : r.matches) {
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(m.S);
      const double major = 3.0 * std::sqrt(es.eigenvalues()[1]);
      const bool inside = m.h.x() - major > 20 && m.h.y() - major > 40 && m.h.x() + major < r.camera.width - 20 &&
                          m.h.y() + major < r.camera.height - 20;
      if (m.searched && inside && major > kept_axis && major < 60.0) {
        kept_axis = major;
        kept = r;
      }
    }
  };
  const pipeline::ImageSlamResult result = pipeline::run_image_slam(ds, o, {}, observer);
  writer.close();
  ASSERT_GT(result.frames.size(), 30u);
  EXPECT_EQ(reports, static_cast<int>(result.frames.size()));
  int pngs = 0;
  for (const auto& e : fs::directory_iterator(dir)) pngs += e.path().extension() == ".png" ? 1 : 0;
  EXPECT_EQ(pngs, static_cast<int>(result.frames.size())) << "one PNG per processed frame";

  // The known landmark: its ellipse in the written PNG, at ±3σ along both principal axes. The overlay draws
  // everything, so the check looks at the landmark's own colour only where no other ellipse passes nearby.
  ASSERT_TRUE(kept.has_value()) << "no searched landmark with a visible ellipse";
  const viz::FrameReport& r = *kept;
  const viz::FrameMatch* known = nullptr;
  for (const auto& m : r.matches) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(m.S);
    if (m.searched && std::abs(3.0 * std::sqrt(es.eigenvalues()[1]) - kept_axis) < 1e-12) known = &m;
  }
  ASSERT_NE(known, nullptr);
  const cv::Mat png =
      io::codecs::imread((dir / viz::OverlayWriter::file_name(r.index, r.t)).string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(png.empty());
  // Redraw the frame with this landmark alone on black, to know which pixels are its ellipse, then require them in
  // the PNG with the landmark's colour.
  viz::FrameReport alone = r;
  alone.matches = {*known};
  alone.landmarks.clear();
  viz::OverlayOptions plain;
  plain.search_regions = false;
  plain.hud = false;
  plain.innovations = false;
  const cv::Mat only = viz::draw_overlay(cv::Mat(), alone, plain);
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(known->S);
  const cv::Scalar colour = viz::match_colour(*known);
  int checked = 0, found = 0;
  for (int axis = 0; axis < 2; ++axis) {
    for (const double s : {-1.0, 1.0}) {
      const Eigen::Vector2d p = known->h + s * 3.0 * std::sqrt(es.eigenvalues()[axis]) * es.eigenvectors().col(axis);
      ASSERT_TRUE(viz::test::colour_near(only, p, colour)) << "the redrawn ellipse passes at 3σ";
      ++checked;
      // In the PNG the ellipse is drawn over the grey image: a pixel next to p has the landmark's colour.
      bool hit = false;
      for (int dy = -1; dy <= 1 && !hit; ++dy) {
        for (int dx = -1; dx <= 1 && !hit; ++dx) {
          const cv::Vec3b q = png.at<cv::Vec3b>(static_cast<int>(std::lround(p.y())) + dy,
                                                static_cast<int>(std::lround(p.x())) + dx);
          const Eigen::Vector3d c(colour[0], colour[1], colour[2]), v(q[0], q[1], q[2]);
          // Coloured like the landmark: its channels ordered as the colour's (grey image pixels are not).
          const double spread = v.maxCoeff() - v.minCoeff();
          hit = spread > 60 && (c.normalized().dot(v.normalized()) > 0.93);
        }
      }
      found += hit ? 1 : 0;
    }
  }
  EXPECT_EQ(checked, 4);
  EXPECT_EQ(found, 4) << "the PNG shows landmark " << known->landmark_id << "'s 3σ ellipse (axis " << kept_axis
                      << " px) at both ends of both axes";
}

}  // namespace
