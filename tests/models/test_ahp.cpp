#include "rtslam/models/landmarks/ahp.hpp"

#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "models/pose_samples.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/models/landmarks/euclidean_point.hpp"
#include "rtslam/models/sensors/pinhole_camera.hpp"
#include "support/jacobian_check.hpp"

namespace rtslam::models {
namespace {

using Eigen::Matrix3d;
using Eigen::MatrixXd;
using Eigen::Vector2d;
using Eigen::Vector3d;
using Eigen::VectorXd;
using test::check_jacobian;
using test::JacobianCheckOptions;
using test::Layout;
using test_samples::sample_poses;
using test_samples::sample_rays;

math::Pose pose_from(const VectorXd& x, int at) {
  return {math::quat_from_wxyz(x.segment<4>(at + 3)), x.segment<3>(at)};
}

VectorXd pose_vector(const math::Pose& T) {
  VectorXd x(7);
  x << T.p, math::quat_to_wxyz(T.q);
  return x;
}

// Landmarks: unit and non-unit m, near and far, at infinity (ρ = 0), tiny ρ.
std::vector<Vector7d> sample_landmarks(std::uint64_t seed) {
  Rng rng(seed);
  std::vector<Vector7d> out;
  Vector7d L;
  L << 0, 0, 0, 0, 0, 1, 0.5;
  out.push_back(L);
  L << 1, -2, 0.5, 0.6, 0.0, 0.8, 0.0;  // at infinity
  out.push_back(L);
  L << 1, -2, 0.5, 0.6, 0.0, 0.8, 1e-9;
  out.push_back(L);
  L << -1, 2, 3, 3.0, -1.5, 2.0, 4.0;  // |m| != 1 (after corrections)
  out.push_back(L);
  for (int i = 0; i < 5; ++i) {
    L << randn_vec<3>(rng, 2.0), randn_vec<3>(rng, 1.0), randu(rng, 0.05, 2.0);
    out.push_back(L);
  }
  return out;
}

TEST(Ahp, FromRayJacobiansMatchNumeric) {
  const Layout in = Layout::euclidean(3).then_quaternion().then_euclidean(4);  // p_WS, q_WS, ray, rho
  for (const math::Pose& T : sample_poses(1)) {
    for (const Vector3d& ray : sample_rays(2)) {
      for (double rho : {0.0, 1e-9, 0.5, 3.0}) {
        Eigen::Matrix<double, 7, 3> Jp;
        Eigen::Matrix<double, 7, 3> Jq;
        Eigen::Matrix<double, 7, 3> Jr;
        Eigen::Matrix<double, 7, 1> Jrho;
        const Vector7d L = ahp_from_ray(T, ray, rho, &Jp, &Jq, &Jr, &Jrho);
        EXPECT_NEAR(L.segment<3>(3).norm(), 1.0, 1e-14);
        EXPECT_EQ(L.head<3>(), T.p);
        EXPECT_EQ(L[6], rho);
        MatrixXd J(7, 10);
        J << Jp, Jq, Jr, Jrho;
        VectorXd x(11);
        x << pose_vector(T), ray, rho;
        const auto f = [](const VectorXd& x) {
          return VectorXd(ahp_from_ray(pose_from(x, 0), x.segment<3>(7), x[10]));
        };
        JacobianCheckOptions opt;
        opt.step = 1e-6 * std::min(1.0, ray.norm());
        EXPECT_TRUE(check_jacobian("ahp_from_ray", f, x, J, in, Layout::euclidean(7), opt));
      }
    }
  }
}

TEST(Ahp, ToSensorJacobiansMatchNumeric) {
  const Layout in = Layout::euclidean(3).then_quaternion().then_euclidean(7);  // p_WS, q_WS, L
  for (const math::Pose& T : sample_poses(3)) {
    for (const Vector7d& L : sample_landmarks(4)) {
      Matrix3d Jp;
      Matrix3d Jq;
      Eigen::Matrix<double, 3, 7> JL;
      ahp_to_sensor(L, T, &Jp, &Jq, &JL);
      MatrixXd J(3, 13);
      J << Jp, Jq, JL;
      VectorXd x(14);
      x << pose_vector(T), L;
      const auto f = [](const VectorXd& x) { return VectorXd(ahp_to_sensor(x.tail<7>(), pose_from(x, 0))); };
      EXPECT_TRUE(check_jacobian("ahp_to_sensor", f, x, J, in, Layout::euclidean(3)));
    }
    // Degenerate: the sensor sits on the anchor (h = R_WSᵀ m, no dependence on ρ).
    Vector7d L;
    L << T.p, 0.0, 0.6, 0.8, 2.0;
    Eigen::Matrix<double, 3, 7> JL;
    const Vector3d h = ahp_to_sensor(L, T, nullptr, nullptr, &JL);
    EXPECT_LT((h - T.q.conjugate() * L.segment<3>(3)).norm(), 1e-14);
    EXPECT_LT(JL.col(6).norm(), 1e-15);
  }
}

TEST(Ahp, ToEuclideanDistanceAndNormalizeJacobiansMatchNumeric) {
  for (const Vector7d& L : sample_landmarks(5)) {
    if (L[6] < 1e-3) continue;  // p = p0 + m/ρ is not defined at infinity (checked separately below)
    Eigen::Matrix<double, 3, 7> Jp;
    ahp_to_euclidean(L, &Jp);
    const auto f = [](const VectorXd& x) { return VectorXd(ahp_to_euclidean(x.head<7>())); };
    JacobianCheckOptions opt;
    opt.step = 1e-7 * L[6];
    EXPECT_TRUE(check_jacobian("ahp_to_euclidean", f, L, Jp, Layout::euclidean(7), Layout::euclidean(3), opt));

    Eigen::Matrix<double, 1, 7> Jd;
    ahp_distance(L, &Jd);
    const auto g = [](const VectorXd& x) { return VectorXd::Constant(1, ahp_distance(x.head<7>())); };
    EXPECT_TRUE(check_jacobian("ahp_distance", g, L, Jd, Layout::euclidean(7), Layout::euclidean(1), opt));
  }
  for (const Vector7d& L : sample_landmarks(6)) {
    Eigen::Matrix<double, 7, 7> Jn;
    const Vector7d Ln = ahp_normalize(L, &Jn);
    EXPECT_NEAR(Ln.segment<3>(3).norm(), 1.0, 1e-15);
    const auto f = [](const VectorXd& x) { return VectorXd(ahp_normalize(x.head<7>())); };
    EXPECT_TRUE(check_jacobian("ahp_normalize", f, L, Jn, Layout::euclidean(7), Layout::euclidean(7)));
  }
  Vector7d inf;
  inf << 0, 0, 0, 0, 0, 1, 0.0;
  EXPECT_FALSE(ahp_to_euclidean(inf).allFinite());
}

TEST(Ahp, InitializationThenObservationGivesBackTheRayAndPixel) {
  CameraIntrinsics intr;
  intr.width = 752;
  intr.height = 480;
  intr.fx = 458.654;
  intr.fy = 457.296;
  intr.cx = 367.215;
  intr.cy = 248.375;
  intr.model = DistortionModel::RadTan;
  intr.coeffs = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  const PinholeCamera cam(intr);
  const AhpPrior prior;
  Rng rng(8);
  for (const math::Pose& T : sample_poses(7)) {
    for (int i = 0; i < 10; ++i) {
      const Vector2d px(randu(rng, 0, 751), randu(rng, 0, 479));
      Vector3d ray;
      ASSERT_TRUE(cam.unproject(px, ray));
      for (double rho : {prior.rho_mean(), prior.rho_mean() + 2 * prior.rho_sigma(), 1e-6}) {
        const Vector7d L = ahp_from_ray(T, ray, rho);
        // Seen from the anchor pose, h_S is along the initial ray (positive scale) for any ρ...
        const Vector3d h = ahp_to_sensor(L, T);
        EXPECT_LT((h.normalized() - ray.normalized()).norm(), 1e-12);
        EXPECT_GT(h.dot(ray), 0.0);
        // ... projects back to the pixel ...
        Vector2d back;
        ASSERT_TRUE(cam.project(h, back));
        EXPECT_LT((back - px).norm(), 1e-9);
        // ... and the Euclidean point is at distance 1/ρ along it.
        const Vector3d p = ahp_to_euclidean(L);
        EXPECT_NEAR((p - T.p).norm(), 1.0 / rho, 1e-9 / rho);
      }
    }
  }
}

TEST(Ahp, AgreesWithTheEuclideanPointFromAnyPose) {
  // h_AHP = ρ · h_Euclidean for the same point (the homogeneous scale), from any other sensor pose.
  const auto poses = sample_poses(9);
  for (const Vector7d& L : sample_landmarks(10)) {
    if (L[6] < 1e-3) continue;
    for (const math::Pose& T : poses) {
      const Vector3d h = ahp_to_sensor(L, T);
      const Vector3d e = point_to_sensor(ahp_to_euclidean(L), T);
      EXPECT_LT((h - L[6] * e).norm(), 1e-12 * (1.0 + h.norm()));
    }
  }
}

TEST(Ahp, GaugeScalingIsTheSamePoint) {
  const auto poses = sample_poses(11);
  Eigen::Matrix<double, 7, 7> P = Eigen::Matrix<double, 7, 7>::Identity() * 1e-4;
  P(6, 6) = 0.01;
  P(3, 6) = P(6, 3) = 2e-4;
  for (const Vector7d& L : sample_landmarks(12)) {
    if (L[6] < 1e-3) continue;
    for (double lambda : {0.1, 2.0, 37.0}) {
      Vector7d Ls = L;
      Ls.segment<4>(3) *= lambda;
      EXPECT_LT((ahp_to_euclidean(Ls) - ahp_to_euclidean(L)).norm(), 1e-12 * (1 + ahp_to_euclidean(L).norm()));
      EXPECT_NEAR(ahp_distance(Ls), ahp_distance(L), 1e-12 * ahp_distance(L));
      for (const math::Pose& T : poses) {
        const Vector3d h = ahp_to_sensor(L, T);
        const Vector3d hs = ahp_to_sensor(Ls, T);
        EXPECT_LT((hs - lambda * h).norm(), 1e-12 * lambda * (1 + h.norm()));
      }
      // The covariance transported by the scaling gives the same linearity index.
      Eigen::Matrix<double, 7, 7> G = Eigen::Matrix<double, 7, 7>::Identity();
      G.block<4, 4>(3, 3) *= lambda;
      const Eigen::Matrix<double, 7, 7> Ps = G * P * G.transpose();
      const Vector3d p_WS(0.3, -0.1, 0.2);
      EXPECT_NEAR(ahp_linearity_index(Ls, Ps, p_WS), ahp_linearity_index(L, P, p_WS),
                  1e-10 * ahp_linearity_index(L, P, p_WS));
    }
    // Normalization picks the |m| = 1 representative of the same point.
    const Vector7d Ln = ahp_normalize(L);
    EXPECT_LT((ahp_to_euclidean(Ln) - ahp_to_euclidean(L)).norm(), 1e-12 * (1 + ahp_to_euclidean(L).norm()));
  }
}

TEST(Ahp, LinearityIndexMatchesHandValueAndDecreasesWithParallax) {
  // Anchor at the origin looking along z at 5 m (ρ = 0.2) with σ_ρ = 0.05: σ_d = σ_ρ/ρ² = 1.25 m.
  Vector7d L;
  L << 0, 0, 0, 0, 0, 1, 0.2;
  Eigen::Matrix<double, 7, 7> P = Eigen::Matrix<double, 7, 7>::Zero();
  P(6, 6) = 0.05 * 0.05;
  // No parallax (sensor at the anchor): L_d = 4 · 1.25 · 1 / 5 = 1.
  EXPECT_NEAR(ahp_linearity_index(L, P, Vector3d::Zero()), 1.0, 1e-12);
  // Sideways baseline b: cos α = 5 / sqrt(25 + b²), d1 = sqrt(25 + b²).
  double prev = 2.0;
  for (double b : {0.1, 0.5, 1.0, 2.0, 5.0, 10.0}) {
    const double li = ahp_linearity_index(L, P, Vector3d(b, 0, 0));
    EXPECT_NEAR(li, 4.0 * 1.25 * 5.0 / (25.0 + b * b), 1e-12) << b;
    EXPECT_LT(li, prev) << b;
    prev = li;
  }
  // Perpendicular view (α = 90°, sensor beside the point): fully linear.
  EXPECT_NEAR(ahp_linearity_index(L, P, Vector3d(3, 0, 5)), 0.0, 1e-15);
  // Point behind the anchor or at infinity: never convert.
  Vector7d Lneg = L;
  Lneg[6] = -0.1;
  EXPECT_TRUE(std::isinf(ahp_linearity_index(Lneg, P, Vector3d(1, 0, 0))));
  Lneg[6] = 0.0;
  EXPECT_TRUE(std::isinf(ahp_linearity_index(Lneg, P, Vector3d(1, 0, 0))));
}

TEST(Ahp, DistanceStdDevMatchesMonteCarlo) {
  // σ_d from the Jacobian agrees with sampling for a small, correlated covariance.
  Vector7d L;
  L << 0.5, -0.2, 0.1, 0.3, 0.4, 1.2, 0.8;
  Eigen::Matrix<double, 7, 7> A = Eigen::Matrix<double, 7, 7>::Zero();
  Rng rng(13);
  for (int i = 0; i < 7; ++i)
    for (int j = 0; j <= i; ++j) A(i, j) = 1e-3 * randn(rng);
  const Eigen::Matrix<double, 7, 7> P = A * A.transpose() + 1e-8 * Eigen::Matrix<double, 7, 7>::Identity();
  Eigen::Matrix<double, 1, 7> Jd;
  const double d = ahp_distance(L, &Jd);
  const double sigma = std::sqrt((Jd * P * Jd.transpose())(0, 0));
  double s = 0.0, s2 = 0.0;
  const int n = 20000;
  for (int k = 0; k < n; ++k) {
    const double dk = ahp_distance(L + A * randn_vec<7>(rng)) - d;
    s += dk;
    s2 += dk * dk;
  }
  const double sd = std::sqrt(s2 / n - (s / n) * (s / n));
  EXPECT_NEAR(sd, sigma, 0.03 * sigma);
}

TEST(Ahp, PriorSpansMinimumDistanceToInfinity) {
  const AhpPrior prior;  // RT-SLAM D_MIN = 0.5 m
  EXPECT_DOUBLE_EQ(prior.rho_mean(), 1.0);
  EXPECT_DOUBLE_EQ(prior.rho_sigma(), 0.5);
  EXPECT_DOUBLE_EQ(1.0 / (prior.rho_mean() + 2 * prior.rho_sigma()), prior.d_min);
  EXPECT_DOUBLE_EQ(prior.rho_mean() - 2 * prior.rho_sigma(), 0.0);
  AhpPrior bad;
  bad.d_min = 0.0;
  EXPECT_THROW(bad.validate(), ConfigError);
  EXPECT_NO_THROW(prior.validate());
}

}  // namespace
}  // namespace rtslam::models
