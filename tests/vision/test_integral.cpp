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
      // The squared-sum table is modulo 2^32 (this frame's total, 8.6e9, exceeds it); sum_sq is exact.
      const auto exact = static_cast<std::uint64_t>(sqsum.at<double>(y, x));
      ASSERT_EQ(ii.sq_table()[i], static_cast<std::uint32_t>(exact));
      ASSERT_EQ(ii.sum_sq(0, 0, x, y), exact);
    }
  // A ROI table gives the same rectangle sums as the whole-image one.
  IntegralImages roi_ii;
  roi_ii.compute(img, Roi{100, 50, 64, 48}, false);
  EXPECT_FALSE(roi_ii.has_squares());
  EXPECT_EQ(roi_ii.sum(110, 60, 30, 20), ii.sum(110, 60, 30, 20));
}

TEST(IntegralImages, EverySimdLevelGivesExactlyTheSameTables) {
  Rng rng(19);
  std::uniform_int_distribution<int> d(0, 1 << 20);
  std::vector<Image> images;
  for (int k = 0; k < 6; ++k) images.push_back(test::random_image(1 + d(rng) % 140, 1 + d(rng) % 40, rng));
  images.emplace_back(200, 30, 255);  // saturated rows
  const auto frames = test::euroc_frames();
  if (!frames.empty()) images.push_back(test::load_gray(frames.front()));
  for (const Image& img : images) {
    // The whole image, then ROIs of every width up to 40 (the SIMD kernels take 16 pixels per step, then a tail).
    std::vector<Roi> rois{img.view().rect()};
    for (int w = 1; w <= 40; ++w) rois.push_back(Roi{d(rng) % img.width(), d(rng) % img.height(), w, 1 + d(rng) % 20});
    for (const Roi& roi : rois) {
      for (const bool squares : {true, false}) {
        IntegralImages ref;
        {
          test::ScopedSimdLevel scalar(SimdLevel::scalar);
          ref.compute(img, roi, squares);
        }
        const Roi r = ref.roi();
        for (const SimdLevel level : test::simd_levels()) {
          test::ScopedSimdLevel guard(level);
          IntegralImages ii;
          ii.compute(img, roi, squares);
          ASSERT_EQ(ii.roi(), r);
          for (int y = 0; y <= r.h; ++y)
            for (int x = 0; x <= r.w; ++x) {
              const std::size_t i = static_cast<std::size_t>(y) * ii.stride() + x;
              ASSERT_EQ(ii.sum_table()[i], ref.sum_table()[i]) << to_string(level) << " at " << x << "," << y;
              if (squares) {
                ASSERT_EQ(ii.sq_table()[i], ref.sq_table()[i]) << to_string(level);
              }
            }
          if (r.empty()) continue;
          // And they give the brute-force sums.
          const int x = r.x + d(rng) % r.w, y = r.y + d(rng) % r.h;
          const int rw = 1 + d(rng) % (r.x + r.w - x), rh = 1 + d(rng) % (r.y + r.h - y);
          std::uint64_t s = 0, q = 0;
          brute_sums(img, x, y, rw, rh, &s, &q);
          ASSERT_EQ(ii.sum(x, y, rw, rh), s);
          if (squares) {
            ASSERT_EQ(ii.sum_sq(x, y, rw, rh), q);
          }
        }
      }
    }
  }
}

TEST(IntegralImages, NoOverflowOnSaturated1280x1024AtEverySimdLevel) {
  const Image img(1280, 1024, 255);
  for (const SimdLevel level : test::simd_levels()) {
    test::ScopedSimdLevel guard(level);
    IntegralImages ii;
    ii.compute(img);
    EXPECT_EQ(ii.sum(0, 0, 1280, 1024), 255u * 1280u * 1024u) << to_string(level);
    EXPECT_EQ(ii.sum_sq(0, 0, 1280, 1024), std::uint64_t{65025} * 1280u * 1024u) << to_string(level);
    EXPECT_EQ(ii.sum_sq(1, 1, 1279, 1023), std::uint64_t{65025} * 1279u * 1023u) << to_string(level);
  }
}

TEST(IntegralImages, SquaredSumsAreExactAtAndBeyondTheModularBoundOnSaturated1280x1024) {
  // 65025 * 66051 < 2^32 <= 65025 * 66052: rectangles up to the bound take one modular difference, larger ones bands.
  ASSERT_LT(std::uint64_t{65025} * IntegralImages::kMaxExactSqPx, std::uint64_t{1} << 32);
  ASSERT_GE(std::uint64_t{65025} * (IntegralImages::kMaxExactSqPx + 1), std::uint64_t{1} << 32);
  const Image img(1280, 1024, 255);
  Rng rng(41);
  std::uniform_int_distribution<int> d(0, 1 << 20);
  for (const SimdLevel level : test::simd_levels()) {
    test::ScopedSimdLevel guard(level);
    IntegralImages ii;
    ii.compute(img);
    auto expect_exact = [&](int x, int y, int w, int h) {
      EXPECT_EQ(ii.sum_sq(x, y, w, h), std::uint64_t{65025} * static_cast<std::uint64_t>(w) * h)
          << to_string(level) << ": " << w << "x" << h << " at " << x << "," << y;
    };
    expect_exact(0, 0, 369, 179);      // 66,051 px: at the bound
    expect_exact(911, 845, 369, 179);  // the same, at the far corner
    expect_exact(0, 0, 196, 337);      // 66,052 px: just beyond, through bands
    expect_exact(1, 1, 1279, 51);      // 65,229 px
    expect_exact(1, 1, 1279, 52);      // 66,508 px
    expect_exact(0, 0, 1280, 1024);    // 8.5e10
    for (int k = 0; k < 200; ++k) {
      const int x = d(rng) % 1280, y = d(rng) % 1024;
      expect_exact(x, y, 1 + d(rng) % (1280 - x), 1 + d(rng) % (1024 - y));
    }
  }
}

TEST(IntegralImages, RowsWiderThan66051PixelsAreExact) {
  // One row of 66,100 saturated pixels already sums above 2^32: sum_sq splits it.
  const Image img(66100, 2, 255);
  for (const SimdLevel level : test::simd_levels()) {
    test::ScopedSimdLevel guard(level);
    IntegralImages ii;
    ii.compute(img);
    EXPECT_EQ(ii.sum_sq(0, 0, 66100, 2), std::uint64_t{65025} * 66100u * 2u) << to_string(level);
    EXPECT_EQ(ii.sum_sq(66000, 1, 100, 1), std::uint64_t{65025} * 100u) << to_string(level);
  }
}
