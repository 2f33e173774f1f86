#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "rtslam/vision/integral.hpp"
#include "vision_test_utils.hpp"

using namespace rtslam::vision;
using rtslam::Rng;

namespace {

// Brute-force sums over a rectangle.
void brute_sums(ImageView img, int x, int y, int w, int h, std::uint64_t* s, std::uint64_t* q) {
  *s = 0;
  *q = 0;
  for (int v = y; v < y + h; ++v)
    for (int u = x; u < x + w; ++u) {
      *s += img.at(u, v);
      *q += static_cast<std::uint64_t>(img.at(u, v)) * img.at(u, v);
    }
}

}  // namespace

TEST(IntegralImages, RectangleSumsEqualBruteForceOnRandomImagesAndRois) {
  Rng rng(7);
  IntegralImages ii;
  std::uniform_int_distribution<int> d(0, 1 << 20);
  for (int trial = 0; trial < 40; ++trial) {
    const int w = 1 + d(rng) % 90, h = 1 + d(rng) % 70;
    const Image img = test::random_image(w, h, rng);
    // ROI, sometimes partly outside the image (clipped).
    const Roi roi{d(rng) % w - 5, d(rng) % h - 5, 1 + d(rng) % (w + 10), 1 + d(rng) % (h + 10)};
    ii.compute(img, roi, true);
    const Roi r = ii.roi();
    ASSERT_EQ(r, roi.intersect(img.view().rect()));
    if (r.empty()) continue;
    for (int k = 0; k < 50; ++k) {
      const int x = r.x + d(rng) % r.w, y = r.y + d(rng) % r.h;
      const int rw = d(rng) % (r.x + r.w - x + 1), rh = d(rng) % (r.y + r.h - y + 1);
      std::uint64_t s = 0, q = 0;
      brute_sums(img, x, y, rw, rh, &s, &q);
      ASSERT_EQ(ii.sum(x, y, rw, rh), s) << "trial " << trial;
      ASSERT_EQ(ii.sum_sq(x, y, rw, rh), q) << "trial " << trial;
    }
  }
}

TEST(IntegralImages, NoOverflowOnSaturated1280x1024) {
  const Image img(1280, 1024, 255);
  IntegralImages ii;
  ii.compute(img);
  EXPECT_EQ(ii.sum(0, 0, 1280, 1024), 255u * 1280u * 1024u);
  EXPECT_EQ(ii.sum_sq(0, 0, 1280, 1024), std::uint64_t{65025} * 1280u * 1024u);
  EXPECT_EQ(ii.sum(1279, 1023, 1, 1), 255u);
  EXPECT_EQ(ii.sum_sq(640, 512, 640, 512), std::uint64_t{65025} * 640u * 512u);
}

TEST(IntegralImages, WholeTablesMatchOpenCvOnARealFrame) {
  const auto frames = test::euroc_frames();
  if (frames.empty()) GTEST_SKIP() << "dataset euroc-v101-static not found";
  const Image img = test::load_gray(frames.front());
  ASSERT_EQ(img.width(), 752);
  IntegralImages ii;
  ii.compute(img);
  cv::Mat sum, sqsum;
  cv::integral(test::to_mat(img), sum, sqsum, CV_32S, CV_64F);
  for (int y = 0; y <= img.height(); y += 7)
    for (int x = 0; x <= img.width(); x += 5) {
      const std::size_t i = static_cast<std::size_t>(y) * ii.stride() + x;
      ASSERT_EQ(static_cast<std::int64_t>(ii.sum_table()[i]), sum.at<int>(y, x));
      ASSERT_EQ(static_cast<double>(ii.sq_table()[i]), sqsum.at<double>(y, x));
    }
  // A ROI table gives the same rectangle sums as the whole-image one.
  IntegralImages roi_ii;
  roi_ii.compute(img, Roi{100, 50, 64, 48}, false);
  EXPECT_FALSE(roi_ii.has_squares());
  EXPECT_EQ(roi_ii.sum(110, 60, 30, 20), ii.sum(110, 60, 30, 20));
}
