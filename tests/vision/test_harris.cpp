#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <optional>

#include <opencv2/imgproc.hpp>

#include "rtslam/vision/harris.hpp"
#include "vision_test_utils.hpp"

using namespace rtslam::vision;
using rtslam::Rng;
using rtslam::randu;

namespace {

struct BruteCorner {
  bool found = false;
  int u = -1, v = -1;
  double score = 0.0;
};

// Plain reference: gradients, window sums, normalized matrix, response, edge test and the first maximum in raster
// order, written from the definitions in harris.hpp without integral images.
void brute_matrix(ImageView img, int u, int v, int ws, double* a, double* b, double* c) {
  const int hw = ws / 2;
  double sxx = 0, syy = 0, sxy = 0;
  for (int y = v - hw; y <= v + hw; ++y)
    for (int x = u - hw; x <= u + hw; ++x) {
      const double dx = static_cast<double>(img.at(x + 1, y)) - img.at(x - 1, y);
      const double dy = static_cast<double>(img.at(x, y + 1)) - img.at(x, y - 1);
      sxx += dx * dx;
      syy += dy * dy;
      sxy += dx * dy;
    }
  const double n = 4.0 * ws * ws;
  *a = sxx / n;
  *b = syy / n;
  *c = sxy / n;
}

BruteCorner brute_best(ImageView img, const Roi& roi, const HarrisOptions& o) {
  const int hw = o.window_size / 2;
  BruteCorner best;
  double best_score = -std::numeric_limits<double>::infinity();
  for (int v = roi.y; v < roi.y + roi.h; ++v)
    for (int u = roi.x; u < roi.x + roi.w; ++u) {
      if (u < o.border_px || v < o.border_px || u > img.width - 1 - o.border_px || v > img.height - 1 - o.border_px)
        continue;
      if (u - hw - 1 < 0 || v - hw - 1 < 0 || u + hw + 1 > img.width - 1 || v + hw + 1 > img.height - 1) continue;
      double a, b, c;
      brute_matrix(img, u, v, o.window_size, &a, &b, &c);
      const double l_max = 0.5 * (a + b) + std::sqrt(0.25 * (a - b) * (a - b) + c * c);
      const double l_min = 0.5 * (a + b) - std::sqrt(0.25 * (a - b) * (a - b) + c * c);
      const double r = o.response == HarrisResponse::harris ? a * b - c * c - o.k * (a + b) * (a + b) : l_min;
      if (r < o.threshold() || !(l_min > 0.0) || l_max > o.edge_ratio * l_min) continue;
      if (r > best_score) {
        best_score = r;
        best = {true, u, v, r};
      }
    }
  return best;
}

// A blurred corner at (x0, y0) along rotated axes: a checkerboard X-corner (bright quadrants +,+ and -,-) or an
// L-corner (bright quadrant +,+ only), rendered by 8x8 supersampling of each pixel's area then a Gaussian blur.
Image render_corner(int w, int h, double x0, double y0, double angle, double blur, bool x_corner) {
  cv::Mat img(h, w, CV_32F);
  const double c = std::cos(angle), s = std::sin(angle);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      double acc = 0;
      for (int j = 0; j < 8; ++j)
        for (int i = 0; i < 8; ++i) {
          const double x = u - 0.5 + (i + 0.5) / 8 - x0, y = v - 0.5 + (j + 0.5) / 8 - y0;
          const double xr = c * x + s * y, yr = -s * x + c * y;
          const bool bright = x_corner ? xr * yr > 0 : (xr > 0 && yr > 0);
          acc += bright ? 200.0 : 50.0;
        }
      img.at<float>(v, u) = static_cast<float>(acc / 64);
    }
  cv::GaussianBlur(img, img, cv::Size(0, 0), blur, blur, cv::BORDER_REFLECT);
  cv::Mat out;
  img.convertTo(out, CV_8U);
  return test::from_mat(out);
}

}  // namespace

TEST(Harris, BestCornerEqualsBruteForceOnRandomAndRealImages) {
  Rng rng(11);
  std::vector<Image> images;
  images.push_back(test::from_mat(test::smooth_texture(160, 120, 1.2, rng)));
  images.push_back(test::random_image(80, 60, rng));
  const auto frames = test::euroc_frames();
  if (!frames.empty()) images.push_back(test::load_gray(frames[10]));
  const Image mono = test::load_gray(test::monoslam_frame(100));
  if (!mono.empty()) images.push_back(mono);
  std::uniform_int_distribution<int> d(0, 1 << 20);
  int n_found = 0, n_trials = 0;
  for (const auto response : {HarrisResponse::harris, HarrisResponse::min_eigen}) {
    for (const int ws : {3, 5, 7}) {
      HarrisOptions o;
      o.response = response;
      o.window_size = ws;
      o.border_px = 3;
      HarrisDetector det(o);
      for (const Image& img : images) {
        for (int k = 0; k < 15; ++k) {
          // ROIs of 8..72 px, sometimes overlapping the image border.
          const int rw = 8 + d(rng) % 65, rh = 8 + d(rng) % 65;
          const Roi roi{d(rng) % (img.width() - 4) - 4, d(rng) % (img.height() - 4) - 4, rw, rh};
          const BruteCorner ref = brute_best(img, roi, o);
          const auto got = det.best_corner(img, roi);
          ++n_trials;
          ASSERT_EQ(got.has_value(), ref.found) << "ws " << ws << " roi " << roi.x << "," << roi.y;
          if (!ref.found) continue;
          ++n_found;
          EXPECT_EQ(got->u_px, ref.u);
          EXPECT_EQ(got->v_px, ref.v);
          EXPECT_NEAR(got->score, ref.score, 1e-9 * std::max(1.0, std::abs(ref.score)));
          EXPECT_LE(std::abs(got->u - got->u_px), 3.0);  // refinement moves at most 3 px (edge lines)
          EXPECT_LE(std::abs(got->v - got->v_px), 3.0);
        }
      }
    }
  }
  EXPECT_GT(n_found, n_trials / 3);  // the comparison is not vacuous
}

TEST(Harris, EverySimdLevelFindsExactlyTheSameCorners) {
  Rng rng(23);
  std::vector<Image> images;
  images.push_back(test::from_mat(test::smooth_texture(150, 110, 1.2, rng)));
  images.push_back(test::random_image(90, 70, rng));
  const auto frames = test::euroc_frames();
  if (!frames.empty()) images.push_back(test::load_gray(frames[20]));
  std::uniform_int_distribution<int> d(0, 1 << 20);
  int n_found = 0, n_brute = 0;
  for (const auto response : {HarrisResponse::harris, HarrisResponse::min_eigen}) {
    for (const int ws : {3, 5, 9}) {
      for (const auto subpixel : {HarrisSubpixel::edge_lines, HarrisSubpixel::quadratic}) {
        HarrisOptions o;
        o.response = response;
        o.window_size = ws;
        o.subpixel = subpixel;
        o.border_px = 2;
        for (const Image& img : images) {
          for (int k = 0; k < 12; ++k) {
            // ROIs of 1..80 px (every tail length of the 4- and 8-lane kernels), some across the image border.
            const Roi roi{d(rng) % img.width() - 6, d(rng) % img.height() - 6, 1 + d(rng) % 80, 1 + d(rng) % 80};
            std::optional<Corner> ref;
            {
              test::ScopedSimdLevel scalar(SimdLevel::scalar);
              ref = HarrisDetector(o).best_corner(img, roi);
            }
            if (k < 3) {  // the scalar level against the brute-force reference
              const BruteCorner brute = brute_best(img, roi, o);
              ASSERT_EQ(ref.has_value(), brute.found);
              ++n_brute;
              if (brute.found) {
                EXPECT_EQ(ref->u_px, brute.u);
                EXPECT_EQ(ref->v_px, brute.v);
                EXPECT_NEAR(ref->score, brute.score, 1e-9 * std::max(1.0, std::abs(brute.score)));
              }
            }
            n_found += ref.has_value();
            for (const SimdLevel level : test::simd_levels()) {
              test::ScopedSimdLevel guard(level);
              const auto got = HarrisDetector(o).best_corner(img, roi);
              ASSERT_EQ(got.has_value(), ref.has_value()) << to_string(level);
              if (!ref) continue;
              EXPECT_EQ(got->u_px, ref->u_px) << to_string(level);
              EXPECT_EQ(got->v_px, ref->v_px) << to_string(level);
              EXPECT_EQ(got->score, ref->score) << to_string(level);  // bit-identical, not only close
              EXPECT_EQ(got->u, ref->u) << to_string(level);
              EXPECT_EQ(got->v, ref->v) << to_string(level);
            }
          }
        }
      }
    }
  }
  EXPECT_GT(n_found, 100);  // the comparison is not vacuous
  // Brute force on the first 3 ROIs of each image and option set (2 responses x 3 windows x 2 fits): 36 per image,
  // 72 without the EuRoC frame (../shared/datasets absent), 108 with it.
  EXPECT_EQ(n_brute, 36 * static_cast<int>(images.size()));
}

TEST(Harris, FindsRenderedCornersWithinAThirdOfAPixel) {
  Rng rng(5);
  for (const bool x_corner : {true, false}) {
    for (const auto subpixel : {HarrisSubpixel::quadratic, HarrisSubpixel::edge_lines}) {
      for (const auto response : {HarrisResponse::harris, HarrisResponse::min_eigen}) {
        HarrisOptions o;
        o.response = response;
        o.subpixel = subpixel;
        HarrisDetector det(o);
        double worst = 0.0;
        for (int k = 0; k < 25; ++k) {
          const double x0 = 32 + randu(rng, -0.5, 0.5), y0 = 30 + randu(rng, -0.5, 0.5);
          const double angle = randu(rng, -0.5, 0.5), blur = randu(rng, 0.7, 1.2);
          const Image img = render_corner(64, 60, x0, y0, angle, blur, x_corner);
          const auto c = det.best_corner(img, Roi{20, 18, 24, 24});
          ASSERT_TRUE(c.has_value());
          worst = std::max(worst, std::hypot(c->u - x0, c->v - y0));
        }
        std::printf("%s corner, %s fit, %s response: worst error %.3f px\n", x_corner ? "X" : "L",
                    subpixel == HarrisSubpixel::quadratic ? "quadratic" : "edge-lines",
                    response == HarrisResponse::harris ? "harris" : "min_eigen", worst);
        if (subpixel == HarrisSubpixel::edge_lines) {
          EXPECT_LT(worst, 0.3);
        } else {
          EXPECT_LT(worst, 2.5);  // the box-window response itself is biased (see docs/vision.md)
        }
      }
    }
  }
}

TEST(Harris, DefaultsFindCornersInTexturedCellsAndNoneInUniformCellsOfRealFrames) {
  const auto frames = test::euroc_frames();
  const Image mono0 = test::load_gray(test::monoslam_frame(0));
  if (frames.empty() || mono0.empty()) GTEST_SKIP() << "dataset euroc-v101-static or monoslam-davison not found";
  struct Set {
    std::vector<Image> images;
    int cell;
  };
  std::vector<Set> sets(2);
  for (const int i : {0, 30, 60, 90}) sets[0].images.push_back(test::load_gray(frames[static_cast<std::size_t>(i)]));
  sets[0].cell = 32;
  for (const int i : {0, 200, 400, 600, 800}) sets[1].images.push_back(test::load_gray(test::monoslam_frame(i)));
  sets[1].cell = 24;
  for (const auto response : {HarrisResponse::harris, HarrisResponse::min_eigen}) {
    HarrisOptions o;
    o.response = response;
    HarrisDetector det(o);
    int n_uniform = 0, n_uniform_hit = 0, n_textured = 0, n_textured_hit = 0;
    for (const Set& set : sets) {
      for (const Image& img : set.images) {
        const cv::Mat m = test::to_mat(img);
        // Independent texture measure: OpenCV's smallest eigenvalue (Sobel 3x3, 5x5 block). For a smooth image its
        // unit is 25 (8 / (4 * 5 * 255))² = 6.15e-5 times ours, so "textured" = a point whose OpenCV λmin is at
        // least 4x our default min_eigen threshold.
        cv::Mat eig;
        cv::cornerMinEigenVal(m, eig, 5, 3);
        const double textured_cv = 4.0 * 6.15e-5 * HarrisOptions{}.min_eigen_threshold;
        const int c = set.cell;
        for (int y = 8; y + c <= img.height() - 8; y += c)
          for (int x = 8; x + c <= img.width() - 8; x += c) {
            cv::Scalar mean, sd;
            cv::meanStdDev(m(cv::Rect(x - 3, y - 3, c + 6, c + 6)), mean, sd);  // the cell and its windows
            double cv_max = 0;
            cv::minMaxLoc(eig(cv::Rect(x, y, c, c)), nullptr, &cv_max);
            const bool hit = det.best_corner(img, Roi{x, y, c, c}).has_value();
            if (sd[0] < 3.0) {
              ++n_uniform;
              n_uniform_hit += hit;
            }
            if (cv_max >= textured_cv) {
              ++n_textured;
              n_textured_hit += hit;
            }
          }
      }
    }
    std::printf("%s: uniform cells %d with a corner %d; textured cells %d with a corner %d\n",
                response == HarrisResponse::harris ? "harris" : "min_eigen", n_uniform, n_uniform_hit, n_textured,
                n_textured_hit);
    EXPECT_GE(n_uniform, 20);
    EXPECT_EQ(n_uniform_hit, 0);
    EXPECT_GE(n_textured, 300);
    EXPECT_GE(n_textured_hit, 0.97 * n_textured);
  }
}

TEST(Harris, UniformImageAndRoisOutsideTheValidAreaYieldNothing) {
  HarrisDetector det;
  const Image flat(64, 64, 128);
  EXPECT_FALSE(det.best_corner(flat, Roi{0, 0, 64, 64}).has_value());
  Rng rng(3);
  const Image tex = test::from_mat(test::smooth_texture(64, 64, 1.0, rng));
  EXPECT_FALSE(det.best_corner(tex, Roi{0, 0, 5, 64}).has_value());   // inside the default 8 px border
  EXPECT_FALSE(det.best_corner(tex, Roi{70, 10, 10, 10}).has_value());  // outside the image
  EXPECT_TRUE(det.best_corner(tex, Roi{8, 8, 48, 48}).has_value());
}

TEST(Harris, ThresholdsAndEdgeRatioAreApplied) {
  Rng rng(9);
  const Image tex = test::from_mat(test::smooth_texture(96, 96, 1.5, rng));
  HarrisOptions o;
  o.response = HarrisResponse::min_eigen;
  o.min_eigen_threshold = 0.0;
  const auto c = HarrisDetector(o).best_corner(tex, Roi{8, 8, 80, 80});
  ASSERT_TRUE(c.has_value());
  o.min_eigen_threshold = c->score * 1.0001;  // just above the best: nothing left
  EXPECT_FALSE(HarrisDetector(o).best_corner(tex, Roi{8, 8, 80, 80}).has_value());
  // A straight edge is rejected by the ratio test, whatever the threshold.
  Image edge(48, 48, 40);
  for (int v = 0; v < 48; ++v)
    for (int u = 24; u < 48; ++u) edge.at(u, v) = 200;
  HarrisOptions oe;
  oe.response = HarrisResponse::min_eigen;
  oe.min_eigen_threshold = 0.0;
  EXPECT_FALSE(HarrisDetector(oe).best_corner(edge, Roi{8, 8, 32, 32}).has_value());
}

TEST(HarrisOptions, YamlIsStrictAndValidated) {
  rtslam::YamlMap good(YAML::Load("{window_size: 7, response: min_eigen, min_eigen_threshold: 30}"), "t.yaml");
  const HarrisOptions o = HarrisOptions::from_yaml(good);
  EXPECT_EQ(o.window_size, 7);
  EXPECT_EQ(o.response, HarrisResponse::min_eigen);
  EXPECT_DOUBLE_EQ(o.threshold(), 30.0);
  rtslam::YamlMap unknown(YAML::Load("{window: 7}"), "t.yaml");
  EXPECT_THROW(HarrisOptions::from_yaml(unknown), rtslam::ConfigError);
  rtslam::YamlMap even(YAML::Load("{window_size: 4}"), "t.yaml");
  EXPECT_THROW(HarrisOptions::from_yaml(even), rtslam::ConfigError);
  rtslam::YamlMap bad_type(YAML::Load("{response: sobel}"), "t.yaml");
  EXPECT_THROW(HarrisOptions::from_yaml(bad_type), rtslam::ConfigError);
}
