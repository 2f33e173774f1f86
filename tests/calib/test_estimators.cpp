// The calibration check's estimators on synthetic data with known answers (noise and outliers included).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "rtslam/calib/check.hpp"
#include "rtslam/calib/estimators.hpp"
#include "rtslam/calib/stream.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::calib {
namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

Matrix3d rot(const Vector3d& theta) { return math::exp_so3(theta).toRotationMatrix(); }
double angle_deg(const Matrix3d& A, const Matrix3d& B) {
  return math::log_so3(Eigen::Quaterniond(A.transpose() * B)).norm() * 180.0 / M_PI;
}

TEST(Kabsch, RecoversARandomRotationExactly) {
  Rng rng(1);
  const Matrix3d R = rot(randn_vec<3>(rng, 1.0));
  std::vector<Vector3d> a, b;
  for (int i = 0; i < 10; ++i) {
    b.push_back(randn_vec<3>(rng));
    a.push_back(R * b.back());
  }
  EXPECT_LT(angle_deg(kabsch(a, b), R), 1e-8);
}

TEST(Kabsch, ReturnsIdentityForDegenerateInput) {
  const std::vector<Vector3d> a = {Vector3d::UnitX(), 2 * Vector3d::UnitX()};
  EXPECT_TRUE(kabsch(a, a).isApprox(Matrix3d::Identity()));
}

// Two views of a random scene 2–6 m away: camera 1 at R_01, t_01 in camera 0; bearings with pixel noise and outliers.
struct TwoViews {
  std::vector<Vector3d> b0, b1;
  Matrix3d R_01;
};
TwoViews make_two_views(Rng& rng, const Vector3d& theta, const Vector3d& t_01, double noise_px, double outliers,
                        int n = 80) {
  const double f = 458.0;
  TwoViews v;
  v.R_01 = rot(theta);
  for (int k = 0; k < n; ++k) {
    const double z = randu(rng, 2.0, 6.0);
    const Vector3d p0(randu(rng, -0.7, 0.7) * z, randu(rng, -0.45, 0.45) * z, z);
    const Vector3d p1 = v.R_01.transpose() * (p0 - t_01);
    Vector3d x0 = p0 / p0.z(), x1 = p1 / p1.z();
    x0.head<2>() += randn_vec<2>(rng, noise_px / f);
    x1.head<2>() += randn_vec<2>(rng, noise_px / f);
    if (randu(rng, 0.0, 1.0) < outliers) x1.head<2>() += Eigen::Vector2d(randu(rng, -0.1, 0.1), randu(rng, -0.1, 0.1));
    v.b0.push_back(x0.normalized());
    v.b1.push_back(x1.normalized());
  }
  return v;
}

RelativeRotationOptions eight_px_options() {
  RelativeRotationOptions o;
  o.ransac_threshold = 8.0 / 458.0;
  o.sampson_threshold = 1.5 / 458.0;
  return o;
}

// Errors (deg) of the epipolar estimate over 20 random two-view problems at 20 Hz: 0.5 rad/s, 1 m/s (1.4 deg, 2.6 cm
// between images), 150 features.
std::vector<double> epipolar_errors(double noise_px, double outliers, std::uint64_t seed) {
  Rng rng(seed);
  std::vector<double> err;
  for (int trial = 0; trial < 20; ++trial) {
    const TwoViews v = make_two_views(rng, randn_vec<3>(rng, 0.015), randn_vec<3>(rng, 0.015), noise_px, outliers, 150);
    const RelativeRotation r = estimate_relative_rotation(v.b0, v.b1, eight_px_options(), rng);
    EXPECT_TRUE(r.ok) << "trial " << trial;
    err.push_back(r.ok ? angle_deg(r.R_01, v.R_01) : 180.0);
  }
  std::sort(err.begin(), err.end());
  return err;
}

TEST(RelativeRotation, EpipolarModelIsExactWithoutNoise) {
  const std::vector<double> e = epipolar_errors(0.0, 0.0, 2);
  EXPECT_LT(e.back(), 1e-4);
}

TEST(RelativeRotation, EpipolarModelWithPixelNoiseStaysAtTheNoiseLevel) {
  const std::vector<double> e = epipolar_errors(0.2, 0.0, 2);
  EXPECT_LT(e.back(), 0.08);
}

TEST(RelativeRotation, EpipolarModelResistsFifteenPercentOutliers) {
  // Outliers displaced by up to ±46 px; the small-baseline epipolar geometry is weak, so a few slip through and cost
  // a tenth of a degree (the hand-eye fit averages the intervals and down-weights the bad ones).
  const std::vector<double> e = epipolar_errors(0.2, 0.15, 2);
  EXPECT_LT(e[e.size() / 2], 0.15) << "median";
  EXPECT_LT(e.back(), 0.4) << "worst";
}

TEST(RelativeRotation, PureRotationModelIsBiasedByTranslationWhichTheEpipolarModelIsNot) {
  // A sideways translation of 5 cm at 2–6 m looks like a rotation to the pure-rotation model.
  Rng rng(3);
  const TwoViews v = make_two_views(rng, Vector3d(0.0, 0.01, 0.0), Vector3d(0.05, 0.0, 0.0), 0.2, 0.0);
  RelativeRotationOptions o = eight_px_options();
  const RelativeRotation epi = estimate_relative_rotation(v.b0, v.b1, o, rng);
  o.epipolar = false;
  const RelativeRotation pure = estimate_relative_rotation(v.b0, v.b1, o, rng);
  ASSERT_TRUE(epi.ok && pure.ok);
  EXPECT_LT(angle_deg(epi.R_01, v.R_01), 0.05);
  EXPECT_GT(angle_deg(pure.R_01, v.R_01), 0.3);
}

TEST(RelativeRotation, RefusesTooFewBearings) {
  Rng rng(4);
  const TwoViews v = make_two_views(rng, Vector3d(0.01, 0, 0), Vector3d::Zero(), 0.2, 0.0, 8);
  EXPECT_FALSE(estimate_relative_rotation(v.b0, v.b1, {}, rng).ok);
}

// A smooth angular velocity in R: a sum of sinusoids per axis (rad/s), up to 1.5 Hz as a hand-held camera.
Vector3d omega_at(double t) {
  return Vector3d(0.6 * std::sin(1.3 * t) + 0.3 * std::sin(4.1 * t + 0.5) + 0.15 * std::sin(9.1 * t),
                  0.5 * std::sin(0.9 * t + 1.0) + 0.25 * std::sin(3.3 * t) + 0.15 * std::sin(8.3 * t + 1.2),
                  0.4 * std::sin(1.7 * t + 2.0) + 0.2 * std::sin(5.2 * t + 0.3) + 0.15 * std::sin(7.7 * t + 2.1));
}

std::vector<io::ImuSample> make_imu(double t_end, const Vector3d& bias, double noise, Rng& rng) {
  std::vector<io::ImuSample> imu;
  for (TimeNs t = 0; to_seconds(t) <= t_end; t += 5'000'000) {
    io::ImuSample s;
    s.t = t;
    s.gyro = omega_at(to_seconds(t)) + bias + randn_vec<3>(rng, noise);
    imu.push_back(s);
  }
  return imu;
}

TEST(IntegrateGyro, ConstantRateGivesRateTimesDuration) {
  std::vector<io::ImuSample> imu;
  for (int k = 0; k <= 100; ++k) imu.push_back({k * 5'000'000LL, Vector3d(0.3, -0.2, 0.1), Vector3d::Zero()});
  const auto th = integrate_gyro(imu, 12'345'678, 212'345'678);
  ASSERT_TRUE(th.has_value());
  EXPECT_LT((*th - 0.2 * Vector3d(0.3, -0.2, 0.1)).norm(), 1e-12);
  const auto with_bias = integrate_gyro(imu, 0, 100'000'000, Vector3d(0.3, -0.2, 0.1));
  EXPECT_LT(with_bias->norm(), 1e-12);
  EXPECT_FALSE(integrate_gyro(imu, 400'000'000, 600'000'000).has_value()) << "beyond the samples";
}

// Camera intervals at 20 Hz over [1, t_end − 1] s: θ_C = R_SR Log ΔR(t0 + t_d, t1 + t_d), with noise and outliers.
std::vector<VisualInterval> make_visual(const std::vector<io::ImuSample>& exact_imu, const Matrix3d& R_RS, double t_d_s,
                                        double t_end, double noise_rad, double outliers, Rng& rng) {
  std::vector<VisualInterval> v;
  for (TimeNs t0 = 1'000'000'000; to_seconds(t0) + 1.05 < t_end; t0 += 50'000'000) {
    VisualInterval iv;
    iv.t0 = t0;
    iv.t1 = t0 + 50'000'000;
    const TimeNs d = from_seconds(t_d_s);
    const auto th = integrate_gyro(exact_imu, iv.t0 + d, iv.t1 + d);
    if (!th) continue;
    iv.theta_C = R_RS.transpose() * *th + randn_vec<3>(rng, noise_rad);
    if (randu(rng, 0.0, 1.0) < outliers) iv.theta_C = randn_vec<3>(rng, 0.05);
    iv.valid = true;
    v.push_back(iv);
  }
  return v;
}

TEST(TimeOffset, RateMagnitudesFindTheOffsetWithinASampleAndTheVectorsRefineIt) {
  Rng rng(5);
  const Matrix3d R_RS = rot(Vector3d(0.3, -1.2, 0.7));
  const std::vector<io::ImuSample> exact = make_imu(10.0, Vector3d::Zero(), 0.0, rng);
  const std::vector<io::ImuSample> noisy = make_imu(10.0, Vector3d(0.02, -0.01, 0.03), 0.03, rng);
  for (double t_d : {0.030, -0.0123, 0.0}) {
    // Visual noise 0.5 mrad per interval (0.01 rad/s of rate; 60 features at 0.3 px give ~0.2 mrad), 5 % outliers.
    const auto visual = make_visual(exact, R_RS, t_d, 10.0, 0.0005, 0.05, rng);
    const TimeOffsetResult r = estimate_time_offset(visual, noisy, 0.0, 0.1, 1e-3);
    ASSERT_TRUE(r.ok);
    EXPECT_NEAR(r.t_d_s, t_d, 5e-3) << "t_d " << t_d;  // the IMU period, with a smooth motion and 5 % outliers
    EXPECT_GT(r.correlation, 0.7);
    // With the rotation and bias known, the vector residual sharpens it.
    const auto refined = refine_time_offset(visual, noisy, R_RS, Vector3d(0.02, -0.01, 0.03), r.t_d_s, 0.02, 1e-3);
    ASSERT_TRUE(refined.has_value());
    EXPECT_NEAR(*refined, t_d, 1.5e-3) << "t_d " << t_d;
  }
}

TEST(TimeOffset, UncorrelatedRatesGiveALowCorrelation) {
  Rng rng(6);
  const std::vector<io::ImuSample> imu = make_imu(10.0, Vector3d::Zero(), 0.0, rng);
  std::vector<VisualInterval> visual;
  for (TimeNs t0 = 1'000'000'000; t0 < 9'000'000'000; t0 += 50'000'000) {
    visual.push_back({t0, t0 + 50'000'000, randn_vec<3>(rng, 0.02), true, 1.0});
  }
  const TimeOffsetResult r = estimate_time_offset(visual, imu, 0.0, 0.1, 1e-3);
  EXPECT_LT(r.correlation, 0.5);
}

TEST(HandEye, RecoversRotationAndBiasWithNoiseAndOutliers) {
  Rng rng(7);
  const Matrix3d R_RS = rot(Vector3d(0.1, 0.2, 1.57));
  const Vector3d bias(0.08, -0.02, 0.01);
  std::vector<Vector3d> wC, wR;
  for (int i = 0; i < 150; ++i) {
    const Vector3d w = omega_at(0.05 * i);
    wR.push_back(w + bias + randn_vec<3>(rng, 0.03));
    wC.push_back(R_RS.transpose() * w + randn_vec<3>(rng, 0.02));
    if (i % 10 == 3) wC.back() = randn_vec<3>(rng, 1.0);  // 10 % tracking failures
  }
  const HandEyeResult r = estimate_hand_eye_rotation(wC, wR, {}, 0.1);
  ASSERT_TRUE(r.ok);
  const double err = angle_deg(r.R_RS, R_RS);
  EXPECT_LT(err, 1.0);
  EXPECT_LT(err, 3.0 * r.rotation_std_deg) << "the std is a sane figure";
  EXPECT_LT((r.gyro_bias - bias).norm(), 0.02);
  EXPECT_GT(r.excitation_rad_s, 0.2);
}

TEST(HandEye, RotationAboutOneAxisIsNotEnough) {
  Rng rng(8);
  std::vector<Vector3d> wC, wR;
  for (int i = 0; i < 100; ++i) {
    const Vector3d w(0.0, 0.0, 0.8 * std::sin(0.2 * i));
    wR.push_back(w + randn_vec<3>(rng, 0.01));
    wC.push_back(w + randn_vec<3>(rng, 0.01));
  }
  const HandEyeResult r = estimate_hand_eye_rotation(wC, wR, {}, 0.1);
  EXPECT_FALSE(r.ok);
  EXPECT_LT(r.excitation_rad_s, 0.05);
}

TEST(StreamTimes, CountsGapsAndDisorderPerStream) {
  StreamTimes st;
  for (TimeNs t : {0LL, 50LL, 100LL, 250LL, 300LL, 300LL, 350LL}) st.add_image(t * 1'000'000);
  for (TimeNs t = 0; t < 1000; t += 5) {
    if (t < 500 || t > 515) st.add_imu(t * 1'000'000);  // a 20 ms dropout
  }
  st.add_imu(990'000'000);  // backwards
  const StreamReport r = st.report(1.5);
  EXPECT_EQ(r.image_gaps, 1u);  // 150 ms against a 50 ms median
  EXPECT_EQ(r.duplicate_timestamps, 1u);
  EXPECT_EQ(r.backwards_timestamps, 1u);
  EXPECT_EQ(r.imu_gaps, 1u);
  EXPECT_NEAR(r.max_imu_interval_ms, 25.0, 1e-9);
  EXPECT_NEAR(r.median_image_interval_ms, 50.0, 1e-9);
  EXPECT_NEAR(r.max_image_interval_ms, 150.0, 1e-9);
}

TEST(CheckOptions, UnknownKeysAndBadValuesAreErrorsNamingTheKey) {
  YAML::Node n = YAML::Load("{duration: 4, max_rotation_deg: 2}");
  YamlMap m(n, "cfg.yaml: imu/calibration_check");
  const CheckOptions o = CheckOptions::from_yaml(m);
  EXPECT_DOUBLE_EQ(o.duration_s, 4.0);
  EXPECT_DOUBLE_EQ(o.max_rotation_deg, 2.0);
  YAML::Node bad = YAML::Load("{durration: 4}");
  YamlMap mb(bad, "cfg.yaml: imu/calibration_check");
  EXPECT_THROW(CheckOptions::from_yaml(mb), ConfigError);
  YAML::Node out = YAML::Load("{max_offset_ms: 0}");
  YamlMap mo(out, "cfg.yaml: imu/calibration_check");
  try {
    CheckOptions::from_yaml(mo);
    FAIL() << "max_offset_ms = 0 accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("max_offset_ms"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rtslam::calib
