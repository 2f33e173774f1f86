// The visual-inertial start (pipeline/vi_init.hpp) on rendered windows of the simulator with its exact ground
// truth: in motion it finds the velocity at the first image and the gravity direction in the body frame, or — in
// windows without enough parallax, or whose tracks do not hold one motion (the 400 deg/s phase of the high-dynamic
// sequence) — says it cannot; a solution it gives is never far off. At rest it says standstill.
#include <gtest/gtest.h>

#include <cstdio>

#include "rtslam/pipeline/vi_init.hpp"
#include "rtslam/sim/simulation.hpp"

namespace rtslam::pipeline {
namespace {

struct Window {
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
    if (t >= t0 && t <= t1) w.frames.push_back({t, s.render_image(k)});
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

}  // namespace
}  // namespace rtslam::pipeline

namespace rtslam::pipeline {
namespace {

// The start's prior fused with |g| = 9.81 ± 0.03: closed form of one scalar Kalman update. The accelerometer bias
// along the vertical is correlated with gravity in the prior (g = −R (f − a_b)), so it takes the difference.
TEST(InertialStart, GravityMagnitudeIsKnown) {
  using I = models::InertialIndex;
  InertialOptions o;
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

}  // namespace
}  // namespace rtslam::pipeline
