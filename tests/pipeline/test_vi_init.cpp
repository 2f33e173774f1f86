// The visual-inertial start (strategies/vi_init.hpp) on rendered windows of the simulator with its exact ground
// truth: in motion it finds the velocity at the first image and the gravity direction in the body frame, also in the
// 400 deg/s phase of the high-dynamic sequence where features leave the view within the window, or — in windows
// without enough parallax, or whose parts do not agree on one motion — says it cannot; a solution it gives is never
// far off. At rest it says standstill.
#include <gtest/gtest.h>

#include <cstdio>

#include "rtslam/strategies/vi_init.hpp"
#include "rtslam/sim/simulation.hpp"

namespace rtslam::strategies {
namespace {

struct Window {
  std::vector<cv::Mat> images;  // the frames' pixels
  std::vector<ViInitFrame> frames;
  std::vector<ImuWindowSample> imu;
  StampedPose truth;  // at the first image
};

Window window_of(const sim::Simulation& s, double from_s, double length_s) {
  Window w;
  const TimeNs t0 = s.image_times().front() + from_seconds(from_s);
  const TimeNs t1 = t0 + from_seconds(length_s);
  for (std::size_t k = 0; k < s.image_times().size(); ++k) {
    const TimeNs t = s.image_times()[k];
    if (t < t0 || t > t1) continue;
    w.images.push_back(s.render_image(k));
    const cv::Mat& m = w.images.back();
    w.frames.push_back({t, vision::ImageView{m.data, m.cols, m.rows, static_cast<int>(m.step[0])}});
  }
  for (const auto& m : s.imu_samples()) {
    if (m.t >= t0 - from_seconds(0.1) && m.t <= t1 + from_seconds(0.1)) w.imu.push_back({m.t, {m.accel, m.gyro}});
  }
  for (const auto& p : s.ground_truth().poses) {
    if (p.t >= w.frames.front().t) {
      w.truth = p;
      break;
    }
  }
  return w;
}

TEST(ViInit, InMotionFindsTheVelocityAndGravity) {
  sim::SimConfig sc = sim::SimConfig::preset("high-dynamic");
  sc.duration_s = 32.0;
  const auto sim = sim::Simulation::create(sc);
  ViInitOptions o;
  int solved = 0;
  for (const double at : {3.0, 8.0, 12.0, 20.0, 29.5, 30.0, 31.0}) {
    const Window w = window_of(*sim, at, o.window_s);
    const ViInitResult r = initialize_visual_inertial(w.frames, w.imu, sim->camera(),
                                                      math::Pose::from_isometry(sim->rig().cameras[0].T_RS), o);
    const Eigen::Matrix3d R_WR = w.truth.q_WR.toRotationMatrix();
    const Eigen::Vector3d v_true = R_WR.transpose() * *w.truth.v_WR;
    const Eigen::Vector3d g_true = R_WR.transpose() * Eigen::Vector3d(0.0, 0.0, -sc.imu.gravity);
    std::printf("t = %.1f s: %s\n  v0 %.3f %.3f %.3f (true %.3f %.3f %.3f), gravity direction off by %.2f deg\n", at,
                r.describe().c_str(), r.v0_R.x(), r.v0_R.y(), r.v0_R.z(), v_true.x(), v_true.y(), v_true.z(),
                std::acos(std::clamp(r.g_R.normalized().dot(g_true.normalized()), -1.0, 1.0)) * 180.0 / M_PI);
    if (r.kind != ViInitResult::Kind::Dynamic) continue;
    ++solved;
    EXPECT_LT((r.v0_R - v_true).norm(), 0.05 + 0.05 * v_true.norm());
    EXPECT_LT(std::acos(std::clamp(r.g_R.normalized().dot(g_true.normalized()), -1.0, 1.0)) * 180.0 / M_PI, 1.0);
  }
  EXPECT_GE(solved, 1);
}

TEST(ViInit, AtRestIsAStandstill) {
  sim::SimConfig sc = sim::SimConfig::preset("high-dynamic");  // 1 s at rest first
  sc.duration_s = 2.0;
  const auto sim = sim::Simulation::create(sc);
  const Window w = window_of(*sim, 0.2, 0.4);
  const ViInitResult r = initialize_visual_inertial(w.frames, w.imu, sim->camera(),
                                                    math::Pose::from_isometry(sim->rig().cameras[0].T_RS), {});
  EXPECT_EQ(r.kind, ViInitResult::Kind::Standstill) << r.describe();
}

// The 400 deg/s phase of the high-dynamic sequence (50 Hz): a corner crosses the image in about ten images, so no
// feature lasts a whole window. Tracks that begin and end inside the window, refilled in the cells the motion empties,
// still give the start; the pixel-error refinement then holds gravity within a degree (the algebraic solution alone
// is 10-20 deg off there). Windows of 1 s, as the growing window reaches them.
TEST(ViInit, FeaturesThatLeaveTheViewStillGiveTheStartAt400DegPerSecond) {
  sim::SimConfig sc = sim::SimConfig::preset("high-dynamic");
  sc.duration_s = 32.5;
  const auto sim = sim::Simulation::create(sc);
  ViInitOptions o;  // the EuRoC preset's acceptance
  o.min_excitation_m = 0.2;
  o.max_reprojection_px = 1.1;
  int solved = 0;
  for (const double at : {30.2, 30.3, 30.6, 30.9, 31.2}) {
    const Window w = window_of(*sim, at, 1.0);
    const ViInitResult r = initialize_visual_inertial(w.frames, w.imu, sim->camera(),
                                                      math::Pose::from_isometry(sim->rig().cameras[0].T_RS), o);
    std::printf("t = %.1f s: %s (%d tracks left the view, %d lost their match)\n", at, r.describe().c_str(),
                r.tracks_left_view, r.tracks_unmatched);
    EXPECT_GT(r.tracks_left_view, r.features / 2) << "the window is meant to lose most of its features";
    if (r.kind != ViInitResult::Kind::Dynamic) continue;
    ++solved;
    const Eigen::Matrix3d R_WR = w.truth.q_WR.toRotationMatrix();
    const Eigen::Vector3d v_true = R_WR.transpose() * *w.truth.v_WR;
    const Eigen::Vector3d g_true = R_WR.transpose() * Eigen::Vector3d(0.0, 0.0, -sc.imu.gravity);
    EXPECT_LT((r.v0_R - v_true).norm(), 0.05 + 0.1 * v_true.norm()) << "t = " << at;
    EXPECT_LT(std::acos(std::clamp(r.g_R.normalized().dot(g_true.normalized()), -1.0, 1.0)) * 180.0 / M_PI, 1.5)
        << "t = " << at;
  }
  EXPECT_GE(solved, 3);
}

// A gyro bias far above the filter's prior (0.05 rad/s per axis; EuRoC's ADIS16448 carries 0.08 about one axis): the
// refinement estimates it with the motion, far better than zero. (Its stated std is too small: about 0.001 rad/s
// where the error about the body y axis is 0.03; the tracks' errors are correlated image to image. Known limitation,
// docs/configuration.md.)
TEST(ViInit, RefinementEstimatesTheGyroBias) {
  sim::SimConfig sc = sim::SimConfig::preset("high-dynamic");
  sc.duration_s = 14.0;
  sc.imu.initial_gyro_bias_std = 0.05;
  const auto sim = sim::Simulation::create(sc);
  ViInitOptions vo;
  int solved = 0;
  for (const double at : {10.5, 11.0, 11.5, 12.0, 12.5}) {
    const Window w = window_of(*sim, at, 1.0);
    const ViInitResult r = initialize_visual_inertial(w.frames, w.imu, sim->camera(),
                                                      math::Pose::from_isometry(sim->rig().cameras[0].T_RS), vo);
    ASSERT_TRUE(w.truth.gyro_bias.has_value());
    const Eigen::Vector3d b_true = *w.truth.gyro_bias;
    std::printf("t = %.1f s: %s\n  gyro bias %.4f %.4f %.4f (true %.4f %.4f %.4f), std %.4f\n", at,
                r.describe().c_str(), r.gyro_bias.x(), r.gyro_bias.y(), r.gyro_bias.z(), b_true.x(), b_true.y(),
                b_true.z(), std::sqrt(r.cov_gyro_bias.trace()));
    if (r.kind != ViInitResult::Kind::Dynamic) continue;
    ++solved;
    EXPECT_LT((r.gyro_bias - b_true).norm(), 0.5 * b_true.norm()) << "t = " << at;
  }
  EXPECT_GE(solved, 2);
}

}  // namespace
}  // namespace rtslam::strategies

namespace rtslam::strategies {
namespace {

// The start's prior fused with |g| = 9.81 ± 0.03: closed form of one scalar Kalman update. The accelerometer bias
// along the vertical is correlated with gravity in the prior (g = −R (f − a_b)), so it takes the difference.
TEST(InertialStart, GravityMagnitudeIsKnown) {
  using I = models::InertialIndex;
  InertialStartOptions o;
  InertialStart s;
  const Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  s.x.segment<3>(I::kG) = Eigen::Vector3d(0.0, 0.0, -9.90);
  s.P = prior_covariance(1.0, o.accel_bias_std, o.gyro_bias_std, o.gravity_std_motion, R);
  const double before_gz = s.P(I::kDg + 2, I::kDg + 2), before_ab = s.P(I::kDab + 2, I::kDab + 2);
  constrain_gravity_magnitude(s, o);
  const double S = before_gz + o.gravity_magnitude_std * o.gravity_magnitude_std;
  // Along g = −z: the innovation is 9.81 − 9.90 = −0.09, the gain before_gz / S.
  EXPECT_NEAR(s.x[I::kG + 2], -9.90 + (before_gz / S) * 0.09, 1e-12);
  EXPECT_NEAR(s.P(I::kDg + 2, I::kDg + 2), before_gz * (1.0 - before_gz / S), 1e-12);
  // The horizontal components (the tilt) keep their prior.
  EXPECT_NEAR(s.P(I::kDg, I::kDg), before_gz, 1e-12);
  // The vertical bias, correlated with g_z by ab² R, moves by its gain and loses variance.
  const double k_ab = o.accel_bias_std * o.accel_bias_std / S;
  EXPECT_NEAR(s.x[I::kAb + 2], k_ab * 0.09, 1e-12);  // |g| = f_z − a_b,z: a smaller |g| is a larger bias
  EXPECT_LT(s.P(I::kDab + 2, I::kDab + 2), before_ab);
  // |g| is now within the constraint's std.
  EXPECT_NEAR(s.x.segment<3>(I::kG).norm(), 9.81, 2.0 * o.gravity_magnitude_std);
}

// The filter's gyro-bias prior after a start in motion: the configured std, or 3σ of the window's estimate when that
// is broader (a short window at 400 deg/s knows the bias to about 0.01 rad/s only).
TEST(InertialStart, GyroBiasPriorCoversTheWindowsEstimate) {
  using I = models::InertialIndex;
  InertialStartOptions o;
  ViInitResult r;
  r.kind = ViInitResult::Kind::Dynamic;
  r.g_R = Eigen::Vector3d(0.0, 0.0, -9.81);
  r.v0_R = Eigen::Vector3d(0.5, 0.0, 0.0);
  r.cov_v_g = 1e-4 * Eigen::Matrix<double, 6, 6>::Identity();
  r.gyro_bias = Eigen::Vector3d(0.01, -0.02, 0.08);
  r.cov_gyro_bias = 1e-8 * Eigen::Matrix3d::Identity();
  const InertialStart tight = inertial_start_from_vi(r, o);
  EXPECT_NEAR(tight.P(I::kDwb, I::kDwb), o.gyro_bias_std * o.gyro_bias_std, 1e-12);
  EXPECT_EQ(tight.x.segment<3>(I::kWb), r.gyro_bias);
  r.cov_gyro_bias = 0.02 * 0.02 * Eigen::Matrix3d::Identity();
  const InertialStart broad = inertial_start_from_vi(r, o);
  EXPECT_NEAR(broad.P(I::kDwb + 2, I::kDwb + 2), 0.06 * 0.06, 1e-9);
}

}  // namespace
}  // namespace rtslam::strategies
