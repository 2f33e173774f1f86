#include "rtslam/models/sensors/pinhole_camera.hpp"

#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "support/jacobian_check.hpp"

namespace rtslam::models {
namespace {

using Eigen::MatrixXd;
using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::VectorXd;
using test::check_jacobian;
using test::JacobianCheckOptions;
using test::Layout;

// EuRoC V1_01 cam0 (sensor.yaml).
CameraIntrinsics euroc_cam0() {
  CameraIntrinsics c;
  c.width = 752;
  c.height = 480;
  c.fx = 458.654;
  c.fy = 457.296;
  c.cx = 367.215;
  c.cy = 248.375;
  c.model = DistortionModel::RadTan;
  c.coeffs = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  return c;
}

CameraIntrinsics base_intrinsics(DistortionModel model, std::vector<double> coeffs) {
  CameraIntrinsics c;
  c.width = 640;
  c.height = 480;
  c.fx = 400.0;
  c.fy = 410.0;
  c.cx = 321.5;
  c.cy = 238.0;
  c.model = model;
  c.coeffs = std::move(coeffs);
  return c;
}

struct NamedCamera {
  std::string name;
  CameraIntrinsics intr;
};

// One camera per model (plus the 5-parameter RadTan), with realistic coefficients.
std::vector<NamedCamera> all_cameras() {
  std::vector<NamedCamera> out;
  out.push_back({"none", base_intrinsics(DistortionModel::None, {})});
  out.push_back({"euroc_radtan", euroc_cam0()});
  out.push_back({"radtan5", base_intrinsics(DistortionModel::RadTan, {-0.3, 0.1, 1e-3, -2e-3, 0.02})});
  // Kalibr equidistant values of a TUM-VI-like fisheye.
  CameraIntrinsics fish =
      base_intrinsics(DistortionModel::Equidistant, {0.0034823, 0.00071508, -0.0020532, 0.00020293});
  fish.fx = fish.fy = 300.0;  // (TUM-VI's 191 px would put the corners beyond 90°: see the equidistant test)
  fish.width = fish.height = 512;
  fish.cx = 254.93;
  fish.cy = 256.90;
  out.push_back({"equidistant", fish});
  // The MonoSLAM Davison camera (camera.json), and a pincushion kappa < 0 variant.
  CameraIntrinsics mono = base_intrinsics(DistortionModel::MonoSlam, {9e-6});
  mono.width = 320;
  mono.height = 240;
  mono.fx = mono.fy = 195.0;
  mono.cx = 162.0;
  mono.cy = 125.0;
  out.push_back({"monoslam", mono});
  CameraIntrinsics mono_neg = base_intrinsics(DistortionModel::MonoSlam, {-2e-6});
  out.push_back({"monoslam_negative_kappa", mono_neg});
  out.push_back({"rtslam_poly", base_intrinsics(DistortionModel::RtslamPoly, {-0.25, 0.06, -0.004})});
  return out;
}

// Points in C covering the centre, the image edges and corners (at a few depths) and random points.
std::vector<Vector3d> grid_points(const PinholeCamera& cam) {
  std::vector<Vector3d> out;
  const auto& k = cam.intrinsics();
  const std::vector<double> us = {0.0, 0.5 * (k.width - 1), k.width - 1.0, 3.0, k.width - 4.0};
  const std::vector<double> vs = {0.0, 0.5 * (k.height - 1), k.height - 1.0, 2.0};
  for (double u : us) {
    for (double v : vs) {
      Vector3d ray;
      if (!cam.unproject(Vector2d(u, v), ray)) continue;
      for (double depth : {0.3, 2.0, 40.0}) out.push_back(depth * ray);
    }
  }
  out.push_back(Vector3d(0.0, 0.0, 1.0));
  out.push_back(Vector3d(1e-9, -1e-9, 1.0));  // on the optical axis: tiny radius
  Rng rng(42);
  for (int i = 0; i < 20; ++i) {
    out.push_back(Vector3d(randu(rng, -0.6, 0.6), randu(rng, -0.45, 0.45), 1.0) * randu(rng, 0.5, 10.0));
  }
  return out;
}

TEST(PinholeCamera, ProjectJacobianMatchesNumericForEveryModel) {
  for (const auto& [name, intr] : all_cameras()) {
    const PinholeCamera cam(intr);
    int checked = 0;
    for (const Vector3d& p : grid_points(cam)) {
      Vector2d px;
      Eigen::Matrix<double, 2, 3> J;
      ASSERT_TRUE(cam.project(p, px, &J)) << name << " at " << p.transpose();
      const auto f = [&cam](const VectorXd& x) {
        Vector2d u;
        cam.project(x.head<3>(), u);
        return VectorXd(u);
      };
      JacobianCheckOptions opt;
      opt.step = 1e-6 * std::max(1e-3, p.norm());
      opt.atol = 1e-4;  // pixels per metre: entries are up to ~1e5 near the camera
      EXPECT_TRUE(check_jacobian(name + " J_px_pC", f, p, J, Layout::euclidean(3), Layout::euclidean(2), opt));
      ++checked;
    }
    EXPECT_GE(checked, 40) << name;  // the fisheye's corners are beyond 90°: no z = 1 ray
  }
}

TEST(PinholeCamera, DistortAndUndistortJacobiansMatchNumeric) {
  for (const auto& [name, intr] : all_cameras()) {
    const PinholeCamera cam(intr);
    for (const Vector3d& p : grid_points(cam)) {
      const Vector2d xy = p.head<2>() / p.z();
      Vector2d xy_d;
      Eigen::Matrix2d Jd;
      ASSERT_TRUE(cam.distort(xy, xy_d, &Jd)) << name;
      const auto f = [&cam](const VectorXd& x) {
        Vector2d out;
        cam.distort(x.head<2>(), out);
        return VectorXd(out);
      };
      JacobianCheckOptions opt;
      opt.atol = 1e-7;
      EXPECT_TRUE(check_jacobian(name + " distort", f, xy, Jd, Layout::euclidean(2), Layout::euclidean(2), opt));

      Vector2d back;
      Eigen::Matrix2d Ju;
      ASSERT_TRUE(cam.undistort(xy_d, back, &Ju)) << name;
      const auto g = [&cam](const VectorXd& x) {
        Vector2d out;
        cam.undistort(x.head<2>(), out);
        return VectorXd(out);
      };
      EXPECT_TRUE(check_jacobian(name + " undistort", g, xy_d, Ju, Layout::euclidean(2), Layout::euclidean(2), opt));
    }
  }
}

TEST(PinholeCamera, UnprojectJacobianMatchesNumeric) {
  for (const auto& [name, intr] : all_cameras()) {
    const PinholeCamera cam(intr);
    Rng rng(5);
    std::vector<Vector2d> pixels = {Vector2d(intr.cx, intr.cy), Vector2d(0, 0),
                                    Vector2d(intr.width - 1.0, intr.height - 1.0), Vector2d(intr.width - 1.0, 0)};
    for (int i = 0; i < 10; ++i) pixels.emplace_back(randu(rng, 0, intr.width - 1.0), randu(rng, 0, intr.height - 1.0));
    for (const Vector2d& px : pixels) {
      Vector3d ray;
      Eigen::Matrix<double, 3, 2> J;
      ASSERT_TRUE(cam.unproject(px, ray, &J)) << name << " at " << px.transpose();
      EXPECT_EQ(ray.z(), 1.0);
      EXPECT_TRUE(J.row(2).isZero(0.0));
      const auto f = [&cam](const VectorXd& x) {
        Vector3d r;
        cam.unproject(x.head<2>(), r);
        return VectorXd(r);
      };
      JacobianCheckOptions opt;
      opt.step = 1e-3;  // pixels
      opt.atol = 1e-9;
      EXPECT_TRUE(check_jacobian(name + " J_ray_px", f, px, J, Layout::euclidean(2), Layout::euclidean(3), opt));
    }
  }
}

TEST(PinholeCamera, ProjectUnprojectRoundTripIsExact) {
  for (const auto& [name, intr] : all_cameras()) {
    const PinholeCamera cam(intr);
    Rng rng(9);
    double worst_px = 0.0;
    for (int i = 0; i < 400; ++i) {
      const Vector2d px(randu(rng, 0, intr.width - 1.0), randu(rng, 0, intr.height - 1.0));
      Vector3d ray;
      ASSERT_TRUE(cam.unproject(px, ray)) << name << " at " << px.transpose();
      Vector2d back;
      ASSERT_TRUE(cam.project(ray * randu(rng, 0.1, 50.0), back)) << name;
      worst_px = std::max(worst_px, (back - px).norm());
    }
    EXPECT_LT(worst_px, 1e-9) << name;
    for (const Vector3d& p : grid_points(cam)) {
      Vector2d px;
      ASSERT_TRUE(cam.project(p, px));
      Vector3d ray;
      ASSERT_TRUE(cam.unproject(px, ray)) << name;
      EXPECT_LT((ray - p / p.z()).norm(), 1e-9) << name << " at " << p.transpose();
    }
  }
}

TEST(PinholeCamera, UnprojectOfAbsurdPixelsEndsWithoutARay) {
  // Newton (the RadTan, Equidistant and RtslamPoly models) compares squared pixel residuals: pixels so far out that
  // a square would overflow must end with "no preimage" or an exact ray, never a non-finite or a wrong one.
  for (const auto& [name, intr] : all_cameras()) {
    if (intr.model == DistortionModel::None || intr.model == DistortionModel::MonoSlam) continue;  // closed forms
    const PinholeCamera cam(intr);
    for (const Vector2d& px : {Vector2d(1e150, -1e150), Vector2d(1e200, 3.0),
                               Vector2d(std::numeric_limits<double>::max(), 0.0)}) {
      Vector3d ray = Vector3d::Zero();
      EXPECT_FALSE(cam.unproject(px, ray)) << name << " at " << px.transpose() << ": ray " << ray.transpose();
    }
    // Far out but finite squares: no preimage, or an exact one.
    for (const Vector2d& px : {Vector2d(-1e6, 1e6), Vector2d(3e4, 2e4)}) {
      Vector3d ray;
      if (!cam.unproject(px, ray)) continue;
      ASSERT_TRUE(ray.allFinite()) << name << " at " << px.transpose();
      Vector2d back;  // (a ray this far off the axis may be refused by project's grazing-angle bound)
      if (cam.project(ray, back)) {
        EXPECT_LE((back - px).cwiseAbs().maxCoeff(), 1e-6 * px.cwiseAbs().maxCoeff())
            << name << " at " << px.transpose() << ": back at " << back.transpose();
      }
    }
  }
}

TEST(PinholeCamera, EurocRadTanMatchesReferenceValues) {
  // Reference pixels computed independently (Python, the MATH.md radial-tangential formula) for EuRoC cam0.
  const CameraIntrinsics intr = euroc_cam0();
  const PinholeCamera cam(intr);
  const std::vector<std::pair<Vector3d, Vector2d>> ref = {
      {Vector3d(0.3, -0.2, 1.0), Vector2d(499.9055685393346, 160.1887446901026)},
      {Vector3d(-0.5, 0.4, 1.2), Vector2d(190.36463513748276, 389.4634327923544)},
      {Vector3d(1.0, 1.0, 4.0), Vector2d(477.9620546899575, 358.8042095192154)}};
  for (const auto& [p, px_ref] : ref) {
    Vector2d px;
    ASSERT_TRUE(cam.project(p, px));
    EXPECT_NEAR(px.x(), px_ref.x(), 1e-9);
    EXPECT_NEAR(px.y(), px_ref.y(), 1e-9);
    Vector3d ray;
    ASSERT_TRUE(cam.unproject(px_ref, ray));
    EXPECT_LT((ray - p / p.z()).norm(), 1e-12);
  }
  // The principal point is a fixed point, and EuRoC's barrel distortion pulls the corners inwards.
  Vector2d c;
  ASSERT_TRUE(cam.project(Vector3d(0, 0, 3), c));
  EXPECT_NEAR(c.x(), intr.cx, 1e-12);
  EXPECT_NEAR(c.y(), intr.cy, 1e-12);
  Vector3d ray;
  ASSERT_TRUE(cam.unproject(Vector2d(0, 0), ray));
  EXPECT_LT(ray.x(), -intr.cx / intr.fx);
  EXPECT_LT(ray.y(), -intr.cy / intr.fy);
}

TEST(PinholeCamera, PointsBehindOrBesideTheCameraAreInvalid) {
  for (const auto& [name, intr] : all_cameras()) {
    const PinholeCamera cam(intr);
    Vector2d px(-7, -7);
    EXPECT_FALSE(cam.project(Vector3d(0.1, 0.2, -1.0), px)) << name;
    EXPECT_FALSE(cam.project(Vector3d(0.0, 0.0, -1e-3), px)) << name;
    EXPECT_FALSE(cam.project(Vector3d(1.0, 0.0, 0.0), px)) << name;  // in the image plane z = 0
    EXPECT_FALSE(cam.project(Vector3d(0.0, 0.0, 0.0), px)) << name;
    EXPECT_FALSE(cam.project(Vector3d(1.0, 0.0, 1e-7), px)) << name;  // grazing: below kMinDepth
    EXPECT_TRUE(cam.project(Vector3d(0.0, 0.0, 1e-7), px)) << name;   // near but in front
  }
}

TEST(PinholeCamera, InImageHonoursTheMargin) {
  const PinholeCamera cam(euroc_cam0());
  EXPECT_TRUE(cam.in_image(Vector2d(0, 0)));
  EXPECT_TRUE(cam.in_image(Vector2d(751, 479)));
  EXPECT_FALSE(cam.in_image(Vector2d(751.01, 100)));
  EXPECT_FALSE(cam.in_image(Vector2d(100, -0.01)));
  EXPECT_FALSE(cam.in_image(Vector2d(4, 100), 5.0));
  EXPECT_TRUE(cam.in_image(Vector2d(5, 100), 5.0));
  EXPECT_TRUE(cam.in_image(Vector2d(746, 474), 5.0));
  EXPECT_FALSE(cam.in_image(Vector2d(746.5, 474), 5.0));
}

TEST(PinholeCamera, ProjectJacobianHoldsAtGrazingAngles) {
  // Points almost in the image plane (|x/z| ~ 1e3, just above kMinDepth): huge but exact derivatives.
  for (const auto& [name, intr] : all_cameras()) {
    if (intr.model == DistortionModel::RadTan || intr.model == DistortionModel::RtslamPoly) continue;  // folded
    const PinholeCamera cam(intr);
    for (const Vector3d& p : {Vector3d(1.0, 0.5, 1e-3), Vector3d(-0.3, 1.0, 2e-6)}) {
      Vector2d px;
      Eigen::Matrix<double, 2, 3> J;
      if (intr.model == DistortionModel::MonoSlam && intr.coeffs[0] < 0) {
        EXPECT_FALSE(cam.project(p, px)) << name;  // outside 1 + 2κ r² > 0
        continue;
      }
      ASSERT_TRUE(cam.project(p, px, &J)) << name << " at " << p.transpose();
      const auto f = [&cam](const VectorXd& x) {
        Vector2d u;
        cam.project(x.head<3>(), u);
        return VectorXd(u);
      };
      JacobianCheckOptions opt;
      opt.step = 1e-4 * p.z();
      opt.rtol = 1e-4;
      opt.atol = 1e-3;
      EXPECT_TRUE(check_jacobian(name + " grazing J_px_pC", f, p, J, Layout::euclidean(3), Layout::euclidean(2), opt));
    }
  }
}

TEST(PinholeCamera, RadTanDomainEndsWhereTheRadialMapFoldsBack) {
  // k = 1 − 0.5 r²: r·k(r) peaks at r² = 2/3 (d/dr = 1 − 1.5 r²).
  const PinholeCamera cam(base_intrinsics(DistortionModel::RadTan, {-0.5, 0.0, 0.0, 0.0}));
  EXPECT_NEAR(cam.max_radius(), std::sqrt(2.0 / 3.0), 1e-9);
  Vector2d px;
  const double r = cam.max_radius();
  EXPECT_TRUE(cam.project(Vector3d(0.999 * r, 0, 1), px));
  EXPECT_FALSE(cam.project(Vector3d(1.001 * r, 0, 1), px));
  EXPECT_FALSE(cam.project(Vector3d(0, 3.0, 1), px));
  // Jacobian and round trip just inside the edge of the domain.
  for (const Vector3d& p : {Vector3d(0.99 * r, 0, 1), Vector3d(0.7 * r, -0.7 * r, 1)}) {
    Eigen::Matrix<double, 2, 3> J;
    ASSERT_TRUE(cam.project(p, px, &J));
    const auto f = [&cam](const VectorXd& x) {
      Vector2d u;
      cam.project(x.head<3>(), u);
      return VectorXd(u);
    };
    JacobianCheckOptions opt;
    opt.atol = 1e-4;
    EXPECT_TRUE(check_jacobian("radtan edge J_px_pC", f, p, J, Layout::euclidean(3), Layout::euclidean(2), opt));
    Vector3d ray;
    ASSERT_TRUE(cam.unproject(px, ray));
    EXPECT_LT((ray - p).norm(), 1e-7);
  }
  // A distorted radius beyond the fold's maximum has no preimage.
  Vector3d ray;
  const double rd_max = r * (1.0 - 0.5 * r * r);
  EXPECT_FALSE(cam.unproject(Vector2d(400.0 * 1.01 * rd_max + 321.5, 238.0), ray));
  // EuRoC's radial map is monotonic everywhere.
  EXPECT_TRUE(std::isinf(PinholeCamera(euroc_cam0()).max_radius()));
}

TEST(PinholeCamera, EquidistantIsExactNearTheAxisAndWideOffIt) {
  const PinholeCamera cam(all_cameras()[3].intr);
  // Near the optical axis (series branch) and just above it (closed form): the map is continuous.
  for (double r : {0.0, 1e-12, 1e-7, 9.9e-6, 1.01e-5, 1e-3}) {
    Vector2d xy_d;
    Eigen::Matrix2d J;
    ASSERT_TRUE(cam.distort(Vector2d(r, 0.5 * r), xy_d, &J));
    if (r > 0) {
      const double rr = r * std::sqrt(1.25);
      const double th = std::atan(rr);
      const auto& k = cam.intrinsics().coeffs;
      const double th_d =
          th * (1 + k[0] * th * th + k[1] * std::pow(th, 4) + k[2] * std::pow(th, 6) + k[3] * std::pow(th, 8));
      EXPECT_NEAR(xy_d.norm(), th_d, 1e-15) << r;
    }
    const auto f = [&cam](const VectorXd& x) {
      Vector2d out;
      cam.distort(x.head<2>(), out);
      return VectorXd(out);
    };
    JacobianCheckOptions opt;
    opt.step = 1e-7;
    EXPECT_TRUE(check_jacobian("equidistant near axis", f, Vector2d(r, 0.5 * r), J, Layout::euclidean(2),
                               Layout::euclidean(2), opt));
  }
  // 80° off axis is still in the domain of this fisheye.
  Vector2d px;
  Eigen::Matrix<double, 2, 3> J;
  const Vector3d p(std::sin(80.0 * M_PI / 180), 0.0, std::cos(80.0 * M_PI / 180));
  ASSERT_TRUE(cam.project(p, px, &J));
  Vector3d ray;
  ASSERT_TRUE(cam.unproject(px, ray));
  EXPECT_LT((ray - p / p.z()).norm(), 1e-8);
  // With TUM-VI's focal length the image corners are seen more than 90° off axis: no z = 1 ray exists.
  CameraIntrinsics tumvi = cam.intrinsics();
  tumvi.fx = tumvi.fy = 190.97;
  const PinholeCamera wide(tumvi);
  EXPECT_FALSE(wide.unproject(Vector2d(0, 0), ray));
  EXPECT_TRUE(wide.unproject(Vector2d(tumvi.cx + 250.0, tumvi.cy), ray));  // θ_d = 1.31 rad
  EXPECT_GT(ray.x(), 3.0);
}

TEST(PinholeCamera, MonoSlamModelWorksOnPixelRadii) {
  const PinholeCamera cam(all_cameras()[4].intr);  // Davison camera, kappa = 9e-6
  // A point 100 px right of the centre (undistorted) lands at r_d = 100 / sqrt(1 + 2·9e-6·100²).
  Vector2d px;
  ASSERT_TRUE(cam.project(Vector3d(100.0 / 195.0, 0.0, 1.0), px));
  EXPECT_NEAR(px.x() - 162.0, 100.0 / std::sqrt(1.0 + 2.0 * 9e-6 * 1e4), 1e-10);
  EXPECT_NEAR(px.y(), 125.0, 1e-12);
  // The inverse formula r_u = r_d / sqrt(1 − 2κ r_d²) on a diagonal pixel.
  Vector3d ray;
  ASSERT_TRUE(cam.unproject(Vector2d(162.0 + 60.0, 125.0 - 80.0), ray));
  const double rd = 100.0;
  const double ru = rd / std::sqrt(1.0 - 2.0 * 9e-6 * rd * rd);
  EXPECT_NEAR(ray.x() * 195.0, 0.6 * ru, 1e-10);
  EXPECT_NEAR(ray.y() * 195.0, -0.8 * ru, 1e-10);
  // With kappa < 0 the distortion is defined only for 1 + 2κ r_u² > 0 (r_u < 500 px for κ = −2e-6).
  const PinholeCamera neg(all_cameras()[5].intr);
  EXPECT_TRUE(neg.project(Vector3d(499.0 / 400.0, 0.0, 1.0), px));
  EXPECT_FALSE(neg.project(Vector3d(501.0 / 400.0, 0.0, 1.0), px));
  // and for kappa > 0 the undistortion only below r_d = 1/sqrt(2κ) = 235.7 px.
  EXPECT_FALSE(cam.unproject(Vector2d(162.0 + 236.0, 125.0), ray));
  EXPECT_TRUE(cam.unproject(Vector2d(162.0 + 235.0, 125.0), ray));
}

TEST(PinholeCamera, RtslamPolyCorrectionPolynomialIsAGoodInverse) {
  const CameraIntrinsics intr = all_cameras()[6].intr;
  const PinholeCamera cam(intr);
  ASSERT_EQ(cam.correction_coeffs().size(), 7u);
  // The fitted correction alone (RT-SLAM's closed-form inverse) is within a small fraction of a pixel over the
  // image; the refined unprojection is exact.
  double worst_corr_px = 0.0;
  for (double u = 0; u <= intr.width - 1; u += 16) {
    for (double v = 0; v <= intr.height - 1; v += 16) {
      const Vector2d xy_d((u - intr.cx) / intr.fx, (v - intr.cy) / intr.fy);
      const Vector2d xy = cam.undistort_by_correction(xy_d);
      Vector2d re;
      ASSERT_TRUE(cam.distort(xy, re));
      worst_corr_px = std::max(worst_corr_px, ((re - xy_d).array() * Eigen::Array2d(intr.fx, intr.fy)).matrix().norm());
    }
  }
  EXPECT_LT(worst_corr_px, 0.05);
  EXPECT_GT(worst_corr_px, 0.0);  // it is a fit, not the exact inverse
  // The first correction coefficient is about −d0 (first-order inverse of 1 + d0 r²).
  EXPECT_NEAR(cam.correction_coeffs()[0], 0.25, 0.02);
}

TEST(PinholeCamera, ValidateNamesTheBadValue) {
  auto expect_error = [](CameraIntrinsics c, const std::string& needle) {
    try {
      c.validate();
      ADD_FAILURE() << "no error for " << needle;
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  CameraIntrinsics c = euroc_cam0();
  EXPECT_NO_THROW(c.validate());
  c.fx = -1.0;
  expect_error(c, "fx = -1");
  c = euroc_cam0();
  c.height = 0;
  expect_error(c, "752x0");
  c = euroc_cam0();
  c.coeffs = {0.1, 0.2, 0.3};
  expect_error(c, "3 coefficients");
  c = euroc_cam0();
  c.coeffs[1] = std::nan("");
  expect_error(c, "coefficient 1 = nan");
  c = euroc_cam0();
  c.model = DistortionModel::Equidistant;
  c.coeffs.push_back(0.0);
  expect_error(c, "equidistant");
  EXPECT_THROW(PinholeCamera{CameraIntrinsics{}}, ConfigError);
  EXPECT_EQ(distortion_model_from_string("radial-tangential"), DistortionModel::RadTan);
  EXPECT_EQ(distortion_model_from_string(to_string(DistortionModel::MonoSlam)), DistortionModel::MonoSlam);
  EXPECT_THROW(distortion_model_from_string("kannala"), ConfigError);
}

}  // namespace
}  // namespace rtslam::models
