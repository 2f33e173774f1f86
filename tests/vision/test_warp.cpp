#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#if defined(__linux__)
#include <sys/mman.h>
#include <unistd.h>
#endif

#include <Eigen/Geometry>

#include "rtslam/vision/warp.hpp"
#include "rtslam/vision/zncc.hpp"
#include "vision_test_utils.hpp"

using namespace rtslam::vision;
using rtslam::Rng;
using rtslam::randu;

namespace {

const PinholeIntrinsics kK{300.0, 300.0, 160.0, 120.0};

Eigen::Vector2d project_test(const PinholeIntrinsics& K, const RigidPose& T_WC, const Eigen::Vector3d& p_W) {
  const Eigen::Vector3d p = T_WC.R.transpose() * (p_W - T_WC.t);
  return {K.fx * p.x() / p.z() + K.cx, K.fy * p.y() / p.z() + K.cy};
}

RigidPose looking_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target, double roll) {
  // Optical frame: z towards the target, x right, y down; then a roll about z.
  const Eigen::Vector3d z = (target - eye).normalized();
  Eigen::Vector3d x = Eigen::Vector3d::UnitY().cross(z);
  if (x.norm() < 1e-6) x = Eigen::Vector3d::UnitX();
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  RigidPose T;
  T.R.col(0) = x;
  T.R.col(1) = y;
  T.R.col(2) = z;
  T.R = T.R * Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.t = eye;
  return T;
}

// Renders the plane Z_W = plane_z textured with `tex` (texel = 200 * (X, Y) + 256) by ray casting each pixel.
Image render_plane(const cv::Mat& tex, const RigidPose& T_WC, double plane_z, int w, int h) {
  Image img(w, h);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      double acc = 0;
      for (int k = 0; k < 4; ++k) {  // 2x2 supersampling
        const double uu = u - 0.25 + 0.5 * (k % 2), vv = v - 0.25 + 0.5 * (k / 2);
        const Eigen::Vector3d d = T_WC.R * Eigen::Vector3d((uu - kK.cx) / kK.fx, (vv - kK.cy) / kK.fy, 1.0);
        const double lambda = (plane_z - T_WC.t.z()) / d.z();
        const Eigen::Vector3d X = T_WC.t + lambda * d;
        acc += test::bilinear(tex, 200.0 * X.x() + 256.0, 200.0 * X.y() + 256.0);
      }
      img.at(u, v) = static_cast<std::uint8_t>(std::lround(acc / 4));
    }
  return img;
}

}  // namespace

TEST(Warp, IdenticalViewsReproduceTheCentreOfTheInitialPatch) {
  Rng rng(1);
  const Image init = test::random_image(31, 31, rng);
  const RigidPose T = looking_at({0.2, -0.1, 0.0}, {0.5, 0.3, 3.0}, 0.3);
  const Eigen::Vector3d p_W = T.t + T.R * Eigen::Vector3d(0.1, -0.05, 2.5);
  const Eigen::Vector2d c0 = project_test(kK, T, p_W);
  Image out(15, 15);
  const WarpResult r = predict_appearance(init, c0, kK, T, T, p_W, out.mutable_view());
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.n_outside, 0);
  EXPECT_NEAR((r.centre_px - c0).norm(), 0.0, 1e-9);
  for (int v = 0; v < 15; ++v)
    for (int u = 0; u < 15; ++u) ASSERT_EQ(out.at(u, v), init.at(u + 8, v + 8));
}

TEST(Warp, HomographyMapsPointsOfTheFrontoParallelPlaneBetweenViews) {
  Rng rng(2);
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Vector3d p_W(randu(rng, -1, 1), randu(rng, -1, 1), randu(rng, 2, 6));
    const RigidPose T0 = looking_at(rtslam::randn_vec<3>(rng, 0.3), p_W, randu(rng, -3, 3));
    const RigidPose T1 = looking_at(rtslam::randn_vec<3>(rng, 0.5), p_W + rtslam::randn_vec<3>(rng, 0.2),
                                    randu(rng, -3, 3));
    Eigen::Matrix3d H;
    ASSERT_TRUE(plane_homography(kK, T0, T1, p_W, &H));
    // Points of the plane through p_W orthogonal to the viewing ray of C0.
    const Eigen::Vector3d n_W = (p_W - T0.t).normalized();
    const Eigen::Vector3d e1 = n_W.unitOrthogonal(), e2 = n_W.cross(e1);
    for (int k = 0; k < 5; ++k) {
      const Eigen::Vector3d X_W = p_W + randu(rng, -0.3, 0.3) * e1 + randu(rng, -0.3, 0.3) * e2;
      const Eigen::Vector2d x0 = project_test(kK, T0, X_W), x1 = project_test(kK, T1, X_W);
      const Eigen::Vector3d h = H * x0.homogeneous();
      EXPECT_NEAR((h.hnormalized() - x1).norm(), 0.0, 1e-6);
    }
  }
}

TEST(Warp, PredictionEqualsDirectRayCastingThroughThePlane) {
  Rng rng(3);
  const Image init = test::from_mat(test::smooth_texture(31, 31, 1.2, rng));
  const cv::Mat init_mat = test::to_mat(init);
  for (int trial = 0; trial < 30; ++trial) {
    const Eigen::Vector3d p_W(randu(rng, -0.5, 0.5), randu(rng, -0.5, 0.5), randu(rng, 2, 4));
    const RigidPose T0 = looking_at(rtslam::randn_vec<3>(rng, 0.2), p_W + rtslam::randn_vec<3>(rng, 0.1), 0.0);
    const RigidPose T1 =
        looking_at(rtslam::randn_vec<3>(rng, 0.3), p_W + rtslam::randn_vec<3>(rng, 0.1), randu(rng, -0.6, 0.6));
    const Eigen::Vector2d c0 = project_test(kK, T0, p_W);
    const Eigen::Vector2d init_centre = c0.array().round();  // the patch was cut at the nearest pixel
    Image out(15, 15);
    const WarpResult r = predict_appearance(init, init_centre, kK, T0, T1, p_W, out.mutable_view());
    ASSERT_TRUE(r.ok);
    const Eigen::Vector2d c1 = project_test(kK, T1, p_W);
    // Plane in W: n·X = n·p_W with n the viewing ray of C0.
    const Eigen::Vector3d n_W = (p_W - T0.t).normalized();
    int n_checked = 0;
    for (int j = 0; j < 15; ++j)
      for (int i = 0; i < 15; ++i) {
        const Eigen::Vector2d q = c1 + Eigen::Vector2d(i - 7, j - 7);
        const Eigen::Vector3d d = T1.R * Eigen::Vector3d((q.x() - kK.cx) / kK.fx, (q.y() - kK.cy) / kK.fy, 1.0);
        const double lambda = n_W.dot(p_W - T1.t) / n_W.dot(d);
        const Eigen::Vector2d x0 = project_test(kK, T0, T1.t + lambda * d);
        const Eigen::Vector2d pc = Eigen::Vector2d(15, 15) + x0 - init_centre;
        if (pc.x() < 0 || pc.y() < 0 || pc.x() > 30 || pc.y() > 30) continue;
        ++n_checked;
        const double expected = test::bilinear(init_mat, pc.x(), pc.y());
        ASSERT_LE(std::abs(out.at(i, j) - expected), 0.5 + 1e-6) << "trial " << trial << " pixel " << i << "," << j;
      }
    EXPECT_GT(n_checked, 100);
  }
}

TEST(Warp, PredictedAppearanceMatchesAfter30DegreesRollAndScale1_5) {
  Rng rng(30);
  const cv::Mat tex = test::smooth_texture(512, 512, 2.0, rng);
  const double plane_z = 2.0;
  const RigidPose T0 = looking_at({0, 0, 0}, {0, 0, 1}, 0.0);
  // Closer by 1.5 (depth 2 -> 4/3) and rolled by 30 degrees about the optical axis.
  const RigidPose T1 = looking_at({0.03, -0.02, plane_z - plane_z / 1.5}, {0.03, -0.02, 1}, 30.0 * M_PI / 180.0);
  const Image img0 = render_plane(tex, T0, plane_z, 320, 240);
  const Image img1 = render_plane(tex, T1, plane_z, 320, 240);
  ZnccMatcher matcher;
  ZnccOptions best_anywhere;  // exhaustive, no threshold: the best score the unwarped patch reaches
  best_anywhere.threshold = -1.0;
  best_anywhere.two_level = false;
  ZnccMatcher exhaustive(best_anywhere);
  int n_pred_ok = 0, n_plain_ok = 0, n = 0;
  for (const Eigen::Vector3d& p_W : {Eigen::Vector3d(0.12, -0.08, 2), Eigen::Vector3d(-0.1, 0.06, 2),
                                    Eigen::Vector3d(0.02, 0.1, 2), Eigen::Vector3d(-0.14, -0.1, 2)}) {
    const Eigen::Vector2d c0 = project_test(kK, T0, p_W);
    const Eigen::Vector2d c1 = project_test(kK, T1, p_W);
    const Eigen::Vector2i ic0 = c0.array().round().cast<int>();
    Patch init, plain;
    ASSERT_TRUE(init.extract(img0, ic0.x(), ic0.y(), 31));
    ASSERT_TRUE(plain.extract(img0, ic0.x(), ic0.y(), 15));
    Image predicted(15, 15);
    const WarpResult w =
        predict_appearance(init.view(), ic0.cast<double>(), kK, T0, T1, p_W, predicted.mutable_view());
    ASSERT_TRUE(w.ok);
    EXPECT_EQ(w.n_outside, 0);
    Patch pred;
    pred.assign(predicted);
    const SearchEllipse e = SearchEllipse::from_covariance(c1, Eigen::Matrix2d::Identity() * 9.0, 3.0);
    const MatchResult a = matcher.match(pred, img1, e);
    const MatchResult b = matcher.match(plain, img1, e);
    const MatchResult b_best = exhaustive.match(plain, img1, e);
    std::printf("point at (%.0f, %.0f): predicted patch score %.3f error %.2f px; unwarped patch best score %.3f\n",
                c1.x(), c1.y(), a.score, std::hypot(a.u - c1.x(), a.v - c1.y()), b_best.score);
    ++n;
    n_pred_ok += a.found && a.score >= 0.9 && std::hypot(a.u - c1.x(), a.v - c1.y()) < 1.0;
    n_plain_ok += b.found;
    EXPECT_LT(b_best.score, 0.9);
  }
  EXPECT_EQ(n_pred_ok, n);
  EXPECT_EQ(n_plain_ok, 0);
}

TEST(Warp, PointBehindACameraIsRejectedAndIdentityDistortionChangesNothing) {
  Rng rng(4);
  const Image init = test::random_image(31, 31, rng);
  const RigidPose T0 = looking_at({0, 0, 0}, {0, 0, 1}, 0.0);
  const RigidPose behind = looking_at({0, 0, 5}, {0, 0, 6}, 0.0);
  Image out(15, 15);
  EXPECT_FALSE(predict_appearance(init, {160, 120}, kK, T0, behind, {0, 0, 3}, out.mutable_view()).ok);
  const RigidPose T1 = looking_at({0.1, 0, 0.2}, {0, 0, 3}, 0.2);
  Image out_plain(15, 15), out_dist(15, 15);
  const Eigen::Vector3d p_W(0.05, 0.02, 3);
  const Eigen::Vector2d c0 = project_test(kK, T0, p_W);
  ASSERT_TRUE(predict_appearance(init, c0, kK, T0, T1, p_W, out_plain.mutable_view()).ok);
  LocalDistortion dist;
  dist.centre0_dist_px = c0;
  ASSERT_TRUE(predict_appearance(init, c0, kK, T0, T1, p_W, out_dist.mutable_view(), &dist).ok);
  for (int v = 0; v < 15; ++v)
    for (int u = 0; u < 15; ++u) ASSERT_EQ(out_plain.at(u, v), out_dist.at(u, v));
  // A distortion that magnifies the current view by 2 changes the patch but keeps the landmark at its centre.
  dist.J_dist_undist = Eigen::Matrix2d::Identity() * 2.0;
  Image out_zoom(15, 15);
  ASSERT_TRUE(predict_appearance(init, c0, kK, T0, T1, p_W, out_zoom.mutable_view(), &dist).ok);
  int n_diff = 0;
  for (int v = 0; v < 15; ++v)
    for (int u = 0; u < 15; ++u) n_diff += out_zoom.at(u, v) != out_plain.at(u, v);
  EXPECT_GT(n_diff, 50);
  EXPECT_EQ(out_zoom.at(7, 7), out_plain.at(7, 7));  // the centre is the landmark in both
}

// Stored patches of 2 or 3 pixels a side, the smallest the AVX2 kernel takes. The patch's bytes are put against an
// inaccessible page, once after their end and once before their start, so that a kernel reading past either end
// (a wider load of a pixel pair, say) faults, whether or not a sanitizer instruments the load. Every level gives
// the same bytes and the same count of pixels outside.
#if defined(__linux__)
class GuardedBytes {
 public:
  GuardedBytes() {
    page_ = static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
    mem_ = ::mmap(nullptr, 3 * page_, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (mem_ == MAP_FAILED) throw std::runtime_error("mmap failed");
    if (::mprotect(mem_, page_, PROT_NONE) != 0 ||
        ::mprotect(static_cast<char*>(mem_) + 2 * page_, page_, PROT_NONE) != 0) {
      ::munmap(mem_, 3 * page_);
      throw std::runtime_error("mprotect failed");
    }
  }
  ~GuardedBytes() { ::munmap(mem_, 3 * page_); }
  GuardedBytes(const GuardedBytes&) = delete;
  GuardedBytes& operator=(const GuardedBytes&) = delete;
  // size bytes that end where the inaccessible page after them starts, or start where the one before them ends.
  std::uint8_t* at_end(std::size_t size) { return static_cast<std::uint8_t*>(mem_) + 2 * page_ - size; }
  std::uint8_t* at_start() { return static_cast<std::uint8_t*>(mem_) + page_; }

 private:
  std::size_t page_ = 0;
  void* mem_ = nullptr;
};
#endif

TEST(Warp, TinyStoredPatchesGiveTheSameBytesOnEveryLevel) {
#if !defined(__linux__)
  GTEST_SKIP() << "needs mmap guard pages";
#else
  GuardedBytes guarded;
  Rng rng(12);
  int inside_pixels = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const int iw = 2 + trial % 2, ih = 2 + (trial / 2) % 2;
    const Image pixels = test::random_image(iw, ih, rng);
    const std::size_t size = static_cast<std::size_t>(iw) * ih;
    std::uint8_t* bytes = (trial / 4) % 2 == 0 ? guarded.at_end(size) : guarded.at_start();  // every size both ways
    std::memcpy(bytes, pixels.view().data, size);
    const ImageView init{bytes, iw, ih, iw};
    const int n = std::array<int, 3>{5, 4, 3}[trial % 3];
    const Eigen::Vector3d p_W(randu(rng, -0.2, 0.2), randu(rng, -0.2, 0.2), randu(rng, 1.0, 3.0));
    const RigidPose T0 = looking_at({0.0, 0.0, 0.0}, p_W, 0.0);
    // Five to eight times closer along the same ray, so that the output patch samples the stored one's interior.
    const RigidPose T1 = looking_at(p_W * randu(rng, 0.8, 0.88), p_W, randu(rng, -1.0, 1.0));
    const Eigen::Vector2d jitter(randu(rng, -0.5, 0.5), randu(rng, -0.5, 0.5));
    const Eigen::Vector2d c0 = project_test(kK, T0, p_W) + jitter;
    std::vector<WarpResult> results;
    std::vector<Image> outs;
    for (const SimdLevel level : test::simd_levels()) {
      test::ScopedSimdLevel scoped(level);
      outs.emplace_back(n, n);
      results.push_back(predict_appearance(init, c0, kK, T0, T1, p_W, outs.back().mutable_view()));
    }
    ASSERT_TRUE(results[0].ok) << "trial " << trial;
    inside_pixels += n * n - results[0].n_outside;
    for (size_t k = 1; k < results.size(); ++k) {
      ASSERT_EQ(results[k].ok, results[0].ok) << "trial " << trial;
      ASSERT_EQ(results[k].n_outside, results[0].n_outside) << "trial " << trial;
      for (int v = 0; v < n; ++v)
        for (int u = 0; u < n; ++u)
          ASSERT_EQ(outs[k].at(u, v), outs[0].at(u, v)) << "trial " << trial << " pixel " << u << "," << v;
    }
  }
  std::printf("pixels inside the stored patches: %d\n", inside_pixels);
  EXPECT_GT(inside_pixels, 1000);
#endif
}

TEST(Warp, EverySimdLevelPredictsTheSameBytes) {
  // Random views of random points, with and without a local distortion model, patches of several sizes (odd and
  // even pixel counts, so the AVX2 kernel's groups of four straddle rows and leave a tail), many of them partly
  // outside the stored patch (its border path) and some with the point behind the current view.
  Rng rng(11);
  const Image init = test::random_image(31, 31, rng);
  const Image init_wide = test::random_image(41, 33, rng);
  int compared = 0, partly_outside = 0, rejected = 0;
  for (int trial = 0; trial < 600; ++trial) {
    const ImageView src = trial % 3 == 0 ? init_wide.view() : init.view();
    const int n = std::array<int, 4>{15, 9, 7, 5}[trial % 4];
    const Eigen::Vector3d p_W(randu(rng, -0.5, 0.5), randu(rng, -0.5, 0.5), randu(rng, 1.0, 5.0));
    const RigidPose T0 = looking_at({randu(rng, -0.2, 0.2), randu(rng, -0.2, 0.2), 0.0}, p_W, randu(rng, -0.3, 0.3));
    const Eigen::Vector3d eye(randu(rng, -1.5, 1.5), randu(rng, -1.0, 1.0), randu(rng, -1.0, 2.5));
    const Eigen::Vector3d aim = p_W + Eigen::Vector3d(randu(rng, -0.3, 0.3), randu(rng, -0.3, 0.3), 0.0);
    const RigidPose T1 = looking_at(eye, trial % 10 == 9 ? 2.0 * eye - aim : aim, randu(rng, -3.0, 3.0));
    const Eigen::Vector2d c0 = project_test(kK, T0, p_W) + Eigen::Vector2d(randu(rng, -2, 2), randu(rng, -2, 2));
    LocalDistortion dist;
    dist.centre0_dist_px = c0 + Eigen::Vector2d(randu(rng, -1, 1), randu(rng, -1, 1));
    dist.J_dist_undist << randu(rng, 0.8, 1.2), randu(rng, -0.1, 0.1), randu(rng, -0.1, 0.1), randu(rng, 0.8, 1.2);
    dist.J_dist_undist_0 << randu(rng, 0.8, 1.2), randu(rng, -0.1, 0.1), randu(rng, -0.1, 0.1), randu(rng, 0.8, 1.2);
    const LocalDistortion* d = trial % 2 ? &dist : nullptr;
    std::vector<WarpResult> results;
    std::vector<Image> outs;
    for (const SimdLevel level : test::simd_levels()) {
      test::ScopedSimdLevel scoped(level);
      outs.emplace_back(n, n);
      results.push_back(predict_appearance(src, c0, kK, T0, T1, p_W, outs.back().mutable_view(), d));
    }
    for (size_t k = 1; k < results.size(); ++k) {
      ASSERT_EQ(results[k].ok, results[0].ok) << "trial " << trial;
      if (!results[0].ok) continue;
      ASSERT_EQ(results[k].n_outside, results[0].n_outside) << "trial " << trial;
      for (int v = 0; v < n; ++v)
        for (int u = 0; u < n; ++u)
          ASSERT_EQ(outs[k].at(u, v), outs[0].at(u, v)) << "trial " << trial << " pixel " << u << "," << v;
    }
    if (results[0].ok) {
      ++compared;
      partly_outside += results[0].n_outside > 0;
    } else {
      ++rejected;
    }
  }
  // The draw reaches every path: whole patches inside, partly outside, and rejected views.
  std::printf("compared %d, partly outside %d, rejected %d\n", compared, partly_outside, rejected);
  EXPECT_GT(compared - partly_outside, 300);
  EXPECT_GT(partly_outside, 20);
  EXPECT_GT(rejected, 30);
}
