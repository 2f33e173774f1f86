#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "rtslam/vision/harris.hpp"
#include "rtslam/vision/zncc.hpp"
#include "vision_test_utils.hpp"

using namespace rtslam::vision;
using rtslam::Rng;
using rtslam::randu;

namespace {

// Plain ZNCC from the definition (double, centred); 0 when the image window is uniform.
double brute_zncc(ImageView patch, ImageView img, int u, int v) {
  const int s = patch.width, h = s / 2;
  double ma = 0, mb = 0;
  for (int y = 0; y < s; ++y)
    for (int x = 0; x < s; ++x) {
      ma += patch.at(x, y);
      mb += img.at(u - h + x, v - h + y);
    }
  ma /= s * s;
  mb /= s * s;
  double ab = 0, aa = 0, bb = 0;
  for (int y = 0; y < s; ++y)
    for (int x = 0; x < s; ++x) {
      const double a = patch.at(x, y) - ma, b = img.at(u - h + x, v - h + y) - mb;
      ab += a * b;
      aa += a * a;
      bb += b * b;
    }
  if (bb == 0.0) return 0.0;
  return ab / std::sqrt(aa * bb);
}

struct Region {
  Eigen::Vector2d c;
  Eigen::Matrix2d Q;  // inverse covariance
  double n;
  bool inside(int u, int v) const {
    const Eigen::Vector2d d(u - c.x(), v - c.y());
    return d.dot(Q * d) <= n * n;
  }
};

struct BruteMatch {
  bool found = false;
  int u = -1, v = -1;
  double score = -2;
  int n_inside = 0;
};

// Exhaustive search over every valid patch centre of the image inside the region (raster order, first maximum).
BruteMatch brute_search(ImageView patch, ImageView img, const Region& r, double threshold) {
  const int h = patch.width / 2;
  BruteMatch m;
  for (int v = h; v < img.height - h; ++v)
    for (int u = h; u < img.width - h; ++u) {
      if (!r.inside(u, v)) continue;
      ++m.n_inside;
      const double s = brute_zncc(patch, img, u, v);
      if (s > m.score) {
        m.score = s;
        m.u = u;
        m.v = v;
      }
    }
  m.found = m.score >= threshold;
  return m;
}

SearchEllipse random_ellipse(const Eigen::Vector2d& c, Rng& rng) {
  const double sx = randu(rng, 2.0, 7.0), sy = randu(rng, 2.0, 7.0), rho = randu(rng, -0.8, 0.8);
  Eigen::Matrix2d cov;
  cov << sx * sx, rho * sx * sy, rho * sx * sy, sy * sy;
  return SearchEllipse::from_covariance(c, cov, 3.0);
}

bool same_result(const MatchResult& a, const MatchResult& b) {
  return a.found == b.found && a.u_px == b.u_px && a.v_px == b.v_px && a.score == b.score && a.u == b.u &&
         a.v == b.v;
}

// Patches selected by Harris in a frame (one per cell), with room for a +-20 px search.
std::vector<std::pair<int, int>> harris_points(ImageView img, int cell) {
  HarrisOptions o;
  o.border_px = 7 + 20;
  HarrisDetector det(o);
  std::vector<std::pair<int, int>> pts;
  for (int y = 0; y < img.height; y += cell)
    for (int x = 0; x < img.width; x += cell)
      if (auto c = det.best_corner(img, Roi{x, y, cell, cell})) pts.emplace_back(c->u_px, c->v_px);
  return pts;
}

}  // namespace

TEST(Zncc, ScoreAtAPositionEqualsBruteForce) {
  Rng rng(21);
  const Image tex = test::from_mat(test::smooth_texture(120, 100, 1.5, rng));
  const Image noise = test::random_image(120, 100, rng);
  ZnccOptions o;
  o.threshold = -1.0;
  o.two_level = false;
  std::uniform_int_distribution<int> d(7, 92);
  for (const bool prune : {false, true}) {
    o.partial_correlation = prune;
    ZnccMatcher m(o);
    for (int k = 0; k < 200; ++k) {
      const Image& img = (k % 2) ? tex : noise;
      Patch p;
      ASSERT_TRUE(p.extract(tex, d(rng), d(rng), 15));
      const int u = d(rng), v = std::min(d(rng), 92);
      const MatchResult r = m.match(p, img, SearchEllipse::box({u, v}, 0.0, 0.0));
      ASSERT_EQ(r.n_evaluated, 1);
      ASSERT_TRUE(r.found);
      EXPECT_NEAR(r.score, brute_zncc(p.view(), img, u, v), 1e-9);
    }
  }
}

TEST(Zncc, ExhaustiveSearchEqualsBruteForceOnRealFrames) {
  const Image f0 = test::load_gray(test::monoslam_frame(40));
  const Image f1 = test::load_gray(test::monoslam_frame(41));
  if (f0.empty() || f1.empty()) GTEST_SKIP() << "dataset monoslam-davison not found";
  Rng rng(4);
  ZnccOptions o;
  o.two_level = false;
  const auto pts = harris_points(f0, 40);
  ASSERT_GE(pts.size(), 20u);
  int n_found = 0;
  for (const bool prune : {false, true}) {
    o.partial_correlation = prune;
    ZnccMatcher m(o);
    for (const auto& [u, v] : pts) {
      Patch p;
      ASSERT_TRUE(p.extract(f0, u, v, 15));
      const SearchEllipse e = random_ellipse({u + randu(rng, -2, 2), v + randu(rng, -2, 2)}, rng);
      const BruteMatch ref = brute_search(p.view(), f1, Region{e.centre, e.inv_cov, e.n_sigma}, o.threshold);
      const MatchResult r = m.match(p, f1, e);
      ASSERT_EQ(r.found, ref.found);
      if (!prune) {
        EXPECT_EQ(r.n_evaluated, ref.n_inside);  // every inside position, and nothing else
      }
      if (!ref.found) continue;
      ++n_found;
      EXPECT_EQ(r.u_px, ref.u);
      EXPECT_EQ(r.v_px, ref.v);
      EXPECT_NEAR(r.score, ref.score, 1e-9);
    }
  }
  EXPECT_GE(n_found, static_cast<int>(pts.size()));  // most patches are found (both passes counted)
}

TEST(Zncc, PositionsOutsideTheEllipseAreNotEvaluated) {
  Rng rng(8);
  const cv::Mat tex = test::smooth_texture(100, 100, 1.5, rng);
  Image img = test::from_mat(tex);
  Patch p;
  ASSERT_TRUE(p.extract(img, 30, 30, 15));
  // A perfect copy of the patch at (62, 62): inside the bounding box of a thin diagonal ellipse centred at
  // (50, 50) along u = -v, but outside the ellipse itself.
  for (int y = 0; y < 15; ++y)
    for (int x = 0; x < 15; ++x) img.at(55 + x, 55 + y) = p.view().at(x, y);
  Eigen::Matrix2d cov;
  cov << 25.0, -24.0, -24.0, 25.0;
  const SearchEllipse e = SearchEllipse::from_covariance({50.0, 50.0}, cov, 3.0);
  ASSERT_TRUE(e.bounding_box().contains(62, 62));
  ASSERT_FALSE(e.contains(62, 62));
  ZnccOptions o;
  o.threshold = -1.0;
  for (const bool two_level : {false, true}) {
    o.two_level = two_level;
    const MatchResult r = ZnccMatcher(o).match(p, img, e);
    EXPECT_TRUE(e.contains(r.u_px, r.v_px));
    EXPECT_LT(r.score, 0.999);
  }
  // With its bounding box as region, the copy is found exactly.
  o.two_level = false;
  const Roi b = e.bounding_box();
  const MatchResult r = ZnccMatcher(o).match(
      p, img, SearchEllipse::box({b.x + 0.5 * (b.w - 1), b.y + 0.5 * (b.h - 1)}, 0.5 * (b.w - 1), 0.5 * (b.h - 1)));
  EXPECT_EQ(r.u_px, 62);
  EXPECT_EQ(r.v_px, 62);
  EXPECT_NEAR(r.score, 1.0, 1e-12);
  EXPECT_EQ(r.n_evaluated, b.w * b.h);
}

TEST(Zncc, BoundedPartialCorrelationNeverChangesTheResult) {
  const Image f0 = test::load_gray(test::monoslam_frame(120));
  const Image f1 = test::load_gray(test::monoslam_frame(121));
  if (f0.empty() || f1.empty()) GTEST_SKIP() << "dataset monoslam-davison not found";
  Rng rng(12);
  long evaluated = 0, pruned = 0;
  int n = 0;
  for (const double threshold : {0.9, 0.5, -1.0}) {
    for (const bool two_level : {false, true}) {
      ZnccOptions o;
      o.threshold = threshold;
      o.two_level = two_level;
      o.partial_correlation = false;
      ZnccMatcher plain(o);
      o.partial_correlation = true;
      ZnccMatcher bounded(o);
      for (const auto& [u, v] : harris_points(f0, 32)) {
        Patch p;
        ASSERT_TRUE(p.extract(f0, u, v, 15));
        const SearchEllipse e = random_ellipse({u + randu(rng, -3, 3), v + randu(rng, -3, 3)}, rng);
        const MatchResult a = plain.match(p, f1, e);
        const MatchResult b = bounded.match(p, f1, e);
        ASSERT_TRUE(same_result(a, b)) << "at " << u << "," << v << " threshold " << threshold;
        EXPECT_EQ(a.n_pruned, 0);
        evaluated += b.n_evaluated;
        pruned += b.n_pruned;
        ++n;
      }
    }
  }
  std::printf("bounded partial correlation: %d searches, %ld positions, %.1f %% abandoned early\n", n, evaluated,
              100.0 * pruned / evaluated);
  EXPECT_GT(pruned, evaluated / 4);  // it does save work
}

// The one-point RANSAC pattern (strategies/active_search.cpp): one template searched again and again in small boxes
// around slightly different predictions, then in an ellipse, sharing a ScoreMemo. Every result must equal the
// search without the memo, which must compute fewer windows. Smoothed random texture (always available) and, when
// present, real frames.
TEST(Zncc, AMemoNeverChangesAResultAndSavesWindows) {
  Rng rng(31);
  std::vector<std::pair<Image, Image>> pairs;
  {
    const cv::Mat a = test::smooth_texture(160, 120, 1.5, rng);
    cv::Mat b;
    const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, 0.4, 0, 1, -0.3);
    cv::warpAffine(a, b, shift, a.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
    pairs.emplace_back(test::from_mat(a), test::from_mat(b));
  }
  const Image f0 = test::load_gray(test::monoslam_frame(120));
  const Image f1 = test::load_gray(test::monoslam_frame(121));
  if (!f0.empty() && !f1.empty()) pairs.emplace_back(f0, f1);
  long with = 0, without = 0, hits_checked = 0;
  for (const double threshold : {0.9, 0.5, -1.0}) {
    ZnccOptions o;
    o.threshold = threshold;
    o.two_level = false;
    ZnccMatcher small(o);
    o.two_level = true;
    ZnccMatcher full(o);
    for (const auto& [img0, img1] : pairs) {
      const int margin = 7 + 12;
      for (int k = 0; k < 30; ++k) {
        const int u = static_cast<int>(randu(rng, margin, img0.width() - margin));
        const int v = static_cast<int>(randu(rng, margin, img0.height() - margin));
        Patch p;
        ASSERT_TRUE(p.extract(img0.view(), u, v, 15));
        if (p.centred_energy() <= 0) continue;
        // 4: a memo that fills up (after 2 entries) must stay correct; 0: one never reserved remembers nothing.
        for (const int capacity : {128, 4, 0}) {
          ScoreMemo memo;
          if (capacity > 0) memo.reserve(capacity);
          // Boxes on a 5 x 5 grid of offsets up to 3 px in a random order: a later box often lacks the peak an
          // earlier one held, so its best is a position an earlier search abandoned against a higher floor.
          std::vector<Eigen::Vector2d> centres;
          for (const double dy : {-3.0, -1.5, 0.0, 1.5, 3.0})
            for (const double dx : {-3.0, -1.5, 0.0, 1.5, 3.0}) centres.emplace_back(u + dx, v + dy);
          std::shuffle(centres.begin(), centres.end(), rng);
          for (const Eigen::Vector2d& c : centres) {
            const SearchEllipse box = SearchEllipse::box(c, 1.0, 1.0);
            const MatchResult a = small.match(p, img1.view(), box);
            const MatchResult b = small.match(p, img1.view(), box, &memo);
            ASSERT_TRUE(same_result(a, b)) << "box at " << c.transpose() << " threshold " << threshold;
            if (capacity == 128) {
              without += a.n_evaluated;
              with += b.n_evaluated;
              ++hits_checked;
            }
          }
          const SearchEllipse e = random_ellipse({u + randu(rng, -3, 3), v + randu(rng, -3, 3)}, rng);
          for (ZnccMatcher* m : {&small, &full}) {
            const MatchResult a = m->match(p, img1.view(), e);
            const MatchResult b = m->match(p, img1.view(), e, &memo);
            ASSERT_TRUE(same_result(a, b)) << "ellipse, two-level " << m->options().two_level;
          }
        }
      }
    }
  }
  std::printf("memo: %ld searches, %ld windows computed against %ld without\n", hits_checked, with, without);
  EXPECT_LT(with, 0.7 * static_cast<double>(without));  
}

TEST(Zncc, EverySimdLevelReturnsExactlyTheSameMatches) {
  // Two frames: real ones when available, else a texture and a shifted copy.
  Rng rng(29);
  Image f0 = test::load_gray(test::monoslam_frame(200)), f1 = test::load_gray(test::monoslam_frame(201));
  if (f0.empty() || f1.empty()) {
    const cv::Mat tex = test::smooth_texture(200, 150, 1.5, rng);
    f0 = test::from_mat(tex);
    const cv::Mat A = (cv::Mat_<double>(2, 3) << 1, 0, 1.3, 0, 1, -0.7);
    cv::Mat shifted;
    cv::warpAffine(tex, shifted, A, tex.size(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    f1 = test::from_mat(shifted);
  }
  int n_found = 0, n_pruned = 0;
  for (const int size : {15, 11, 21, 31}) {  // one or two 16-byte blocks per template row
    for (const bool two_level : {true, false}) {
      for (const bool partial : {true, false}) {
        ZnccOptions o;
        o.patch_size = size;
        o.two_level = two_level;
        o.partial_correlation = partial;
        o.threshold = 0.5;
        for (int k = 0; k < 12; ++k) {
          const int h = size / 2;
          const int u = h + static_cast<int>(randu(rng, 0, f0.width() - 2 * h - 1));
          const int v = h + static_cast<int>(randu(rng, 0, f0.height() - 2 * h - 1));
          Patch p;
          ASSERT_TRUE(p.extract(f0, u, v, size));
          // Ellipses, and boxes reaching the right border (where rows cannot be read over the padded width).
          const SearchEllipse e = k % 3 == 0   ? random_ellipse({u + randu(rng, -3, 3), v + randu(rng, -3, 3)}, rng)
                                  : k % 3 == 1 ? SearchEllipse::box({u + 1.0, v - 1.0}, 12.0, 9.0)
                                               : SearchEllipse::box({f1.width() - 1.0 - h, v + 0.0}, 14.0, 10.0);
          MatchResult ref;
          {
            test::ScopedSimdLevel scalar(SimdLevel::scalar);
            ref = ZnccMatcher(o).match(p, f1, e);
          }
          n_found += ref.found;
          n_pruned += ref.n_pruned;
          for (const SimdLevel level : test::simd_levels()) {
            test::ScopedSimdLevel guard(level);
            const MatchResult r = ZnccMatcher(o).match(p, f1, e);
            ASSERT_TRUE(same_result(r, ref)) << to_string(level) << " size " << size << " at " << u << "," << v;
            EXPECT_EQ(r.n_evaluated, ref.n_evaluated) << to_string(level);
            EXPECT_EQ(r.n_pruned, ref.n_pruned) << to_string(level);
          }
        }
      }
    }
  }
  EXPECT_GT(n_found, 50);  // the comparison is not vacuous
  EXPECT_GT(n_pruned, 0);
}

namespace {

struct Agreement {
  int trials = 0, same = 0, found = 0;
};

void compare_two_level(ImageView f0, ImageView f1, const std::vector<std::pair<int, int>>& pts,
                       const std::vector<Eigen::Vector2d>& predicted, Agreement* agg) {
  ZnccOptions o;
  o.two_level = false;
  ZnccMatcher exhaustive(o);
  o.two_level = true;
  ZnccMatcher two_level(o);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    Patch p;
    if (!p.extract(f0, pts[i].first, pts[i].second, 15)) continue;
    const Eigen::Vector2d c(std::round(predicted[i].x()), std::round(predicted[i].y()));
    const SearchEllipse box = SearchEllipse::box(c, 20.0, 20.0);  // 41 x 41 positions
    const MatchResult a = exhaustive.match(p, f1, box);
    const MatchResult b = two_level.match(p, f1, box);
    ++agg->trials;
    agg->found += a.found;
    agg->same += (a.found == b.found) && (!a.found || (a.u_px == b.u_px && a.v_px == b.v_px));
  }
}

}  // namespace

TEST(Zncc, TwoLevelFindsTheExhaustiveBestOnTrackedMonoSlamFrames) {
  if (test::load_gray(test::monoslam_frame(0)).empty()) GTEST_SKIP() << "dataset monoslam-davison not found";
  Agreement agg;
  for (int k = 0; k < 990; k += 15) {
    const Image f0 = test::load_gray(test::monoslam_frame(k));
    const Image f1 = test::load_gray(test::monoslam_frame(k + 1));
    const auto pts = harris_points(f0, 32);
    std::vector<Eigen::Vector2d> pred;
    for (const auto& [u, v] : pts) pred.emplace_back(u, v);  // frame k position: the motion is unknown
    compare_two_level(f0, f1, pts, pred, &agg);
  }
  const double rate = static_cast<double>(agg.same) / agg.trials;
  std::printf("monoslam k->k+1: %d trials (%d matched by exhaustive search), two-level agrees on %.2f %%\n",
              agg.trials, agg.found, 100.0 * rate);
  EXPECT_GE(agg.trials, 500);
  EXPECT_GE(agg.found, agg.trials / 2);
  EXPECT_GE(rate, 0.99);
}

TEST(Zncc, TwoLevelFindsTheExhaustiveBestOnSyntheticWarpsOfEurocFrames) {
  const auto frames = test::euroc_frames();
  if (frames.empty()) GTEST_SKIP() << "dataset euroc-v101-static not found";
  Rng rng(31);
  Agreement agg;
  int n_at_truth = 0;
  for (std::size_t i = 0; i < frames.size(); i += 8) {
    const Image f0 = test::load_gray(frames[i]);
    // Known warp about the image centre: rotation, scale and sub-pixel translation.
    const double angle = randu(rng, -6.0, 6.0), scale = randu(rng, 0.94, 1.06);
    cv::Mat A = cv::getRotationMatrix2D(cv::Point2f(375.5f, 239.5f), angle, scale);
    A.at<double>(0, 2) += randu(rng, -4.0, 4.0);
    A.at<double>(1, 2) += randu(rng, -4.0, 4.0);
    cv::Mat warped;
    cv::warpAffine(test::to_mat(f0), warped, A, cv::Size(f0.width(), f0.height()), cv::INTER_LINEAR,
                   cv::BORDER_REPLICATE);
    const Image f1 = test::from_mat(warped);
    const auto pts = harris_points(f0, 48);
    std::vector<Eigen::Vector2d> pred;
    for (const auto& [u, v] : pts)
      pred.emplace_back(A.at<double>(0, 0) * u + A.at<double>(0, 1) * v + A.at<double>(0, 2),
                        A.at<double>(1, 0) * u + A.at<double>(1, 1) * v + A.at<double>(1, 2));
    compare_two_level(f0, f1, pts, pred, &agg);
    // The sub-pixel match lands near the known position.
    ZnccMatcher m;
    for (std::size_t j = 0; j < pts.size(); ++j) {
      Patch p;
      p.extract(f0, pts[j].first, pts[j].second, 15);
      const MatchResult r = m.match(p, f1, SearchEllipse::box(pred[j].array().round(), 20.0, 20.0));
      n_at_truth += r.found && std::hypot(r.u - pred[j].x(), r.v - pred[j].y()) < 1.0;
    }
  }
  const double rate = static_cast<double>(agg.same) / agg.trials;
  std::printf("euroc synthetic warps: %d trials (%d matched by exhaustive search, %d within 1 px of the truth), "
              "two-level agrees on %.2f %%\n", agg.trials, agg.found, n_at_truth, 100.0 * rate);
  EXPECT_GE(agg.trials, 500);
  EXPECT_GE(n_at_truth, 0.85 * agg.trials);
  EXPECT_GE(rate, 0.99);
}

TEST(Zncc, SubPixelPeakWithinATenthOfAPixelOnBilinearShifts) {
  Rng rng(17);
  const cv::Mat tex = test::smooth_texture(120, 120, 2.0, rng);
  const Image img0 = test::from_mat(tex);
  ZnccMatcher m;
  double worst = 0.0;
  for (int k = 0; k < 40; ++k) {
    const double su = randu(rng, -3.5, 3.5), sv = randu(rng, -3.5, 3.5);
    cv::Mat shifted(tex.rows, tex.cols, CV_8U);
    for (int v = 0; v < tex.rows; ++v)
      for (int u = 0; u < tex.cols; ++u)
        shifted.at<std::uint8_t>(v, u) = static_cast<std::uint8_t>(std::lround(test::bilinear(tex, u - su, v - sv)));
    const Image img1 = test::from_mat(shifted);
    const int u0 = 50 + k % 20, v0 = 45 + (k * 7) % 25;
    Patch p;
    ASSERT_TRUE(p.extract(img0, u0, v0, 15));
    const MatchResult r = m.match(p, img1, SearchEllipse::box({u0, v0}, 6.0, 6.0));
    ASSERT_TRUE(r.found);
    worst = std::max(worst, std::hypot(r.u - (u0 + su), r.v - (v0 + sv)));
  }
  std::printf("zncc sub-pixel worst error: %.3f px\n", worst);
  EXPECT_LT(worst, 0.1);
}

TEST(Zncc, UniformTemplatesAndRegionsOutsideTheImageFindNothing) {
  Rng rng(2);
  const Image img = test::from_mat(test::smooth_texture(64, 64, 1.5, rng));
  ZnccMatcher m;
  Patch flat;
  flat.assign(Image(15, 15, 77));
  EXPECT_FALSE(m.match(flat, img, SearchEllipse::box({32, 32}, 10, 10)).found);
  Patch p;
  ASSERT_TRUE(p.extract(img, 32, 32, 15));
  EXPECT_FALSE(p.extract(img, 3, 32, 15));  // does not fit: unchanged
  EXPECT_EQ(p.size(), 15);
  const MatchResult out = m.match(p, img, SearchEllipse::box({200, 32}, 10, 10));
  EXPECT_FALSE(out.found);
  EXPECT_EQ(out.n_evaluated, 0);
  const MatchResult self = m.match(p, img, SearchEllipse::box({30, 33}, 5, 5));
  EXPECT_TRUE(self.found);
  EXPECT_EQ(self.u_px, 32);
  EXPECT_EQ(self.v_px, 32);
}

TEST(ZnccOptions, YamlIsStrictAndValidated) {
  rtslam::YamlMap good(YAML::Load("{threshold: 0.8, patch_size: 11, two_level: false}"), "t.yaml");
  const ZnccOptions o = ZnccOptions::from_yaml(good);
  EXPECT_DOUBLE_EQ(o.threshold, 0.8);
  EXPECT_EQ(o.patch_size, 11);
  EXPECT_FALSE(o.two_level);
  rtslam::YamlMap bad(YAML::Load("{threshold: 1.5}"), "t.yaml");
  EXPECT_THROW(ZnccOptions::from_yaml(bad), rtslam::ConfigError);
  rtslam::YamlMap unknown(YAML::Load("{treshold: 0.5}"), "t.yaml");
  EXPECT_THROW(ZnccOptions::from_yaml(unknown), rtslam::ConfigError);
}
