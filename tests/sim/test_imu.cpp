// IMU synthesis: integration of noise-free samples reproduces the trajectory, the accelerometer convention matches
// the real EuRoC V1_01 data, noise statistics follow the continuous-time densities, seeds, saturation.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>

#include <gtest/gtest.h>

#include "rtslam/io/trajectory_io.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/sim/imu.hpp"
#include "rtslam/sim/trajectory.hpp"

namespace rtslam::sim {
namespace {

using Eigen::Quaterniond;
using Eigen::Vector3d;

// Integrates IMU samples with the midpoint rule of MATH.md ("Robots", inertial) from the true initial state.
struct Integrated {
  Vector3d p, v;
  Quaterniond q;
};
Integrated integrate_midpoint(const std::vector<SynthImuSample>& s, const KinematicState& x0, double gravity) {
  Integrated x{x0.p_WR, x0.v_WR, x0.q_WR};
  const Vector3d g(0, 0, -gravity);
  for (std::size_t k = 0; k + 1 < s.size(); ++k) {
    const double dt = to_seconds(s[k + 1].t - s[k].t);
    const Vector3d w_bar = 0.5 * (s[k].gyro + s[k + 1].gyro);
    const Quaterniond q_next = math::boxplus(x.q, w_bar * dt);
    const Vector3d a_bar = 0.5 * (x.q * s[k].accel + q_next * s[k + 1].accel) + g;
    x.p += x.v * dt + 0.5 * a_bar * dt * dt;
    x.v += a_bar * dt;
    x.q = q_next;
  }
  return x;
}

std::vector<SynthImuSample> synthesize(const ContinuousTrajectory& traj, const ImuSynthOptions& opt,
                                       std::uint64_t seed, double duration_s) {
  ImuSynthesizer imu(traj, opt, Rng(seed));
  std::vector<SynthImuSample> out;
  const TimeNs period = from_seconds(1.0 / opt.rate_hz);
  for (TimeNs t = traj.t_begin(); t <= traj.t_begin() + from_seconds(duration_s); t += period)
    out.push_back(imu.sample(t));
  return out;
}

ImuSynthOptions noise_free() {
  ImuSynthOptions opt;
  opt.noise_enabled = false;
  opt.initial_accel_bias_std = 0.0;
  opt.initial_gyro_bias_std = 0.0;
  return opt;
}

TEST(ImuSynthesis, MidpointIntegrationOfNoiseFreeHandheldReproducesTheTrajectory) {
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    const auto traj = make_handheld(seed, Vector3d(0, 0, 1.5), 12.0);
    const auto samples = synthesize(*traj, noise_free(), seed, 10.0);
    ASSERT_EQ(samples.size(), 2001u);
    const Integrated x = integrate_midpoint(samples, traj->at(traj->t_begin()), 9.81);
    const KinematicState truth = traj->at(samples.back().t);
    EXPECT_LT((x.p - truth.p_WR).norm(), 0.01) << "seed " << seed;
    EXPECT_LT((x.v - truth.v_WR).norm(), 0.005) << "seed " << seed;
    EXPECT_LT(math::boxminus(x.q, truth.q_WR).norm(), 1e-3) << "seed " << seed;
    // The trajectory really moved (the check is not trivial).
    EXPECT_GT((truth.p_WR - traj->at(traj->t_begin()).p_WR).norm(), 0.1);
  }
}

TEST(ImuSynthesis, WrongGravitySignIsDetectedByIntegration) {
  // The same integration with the sign convention flipped must fail: guards against a tautological check.
  const auto traj = make_handheld(1, Vector3d(0, 0, 1.5), 12.0);
  auto samples = synthesize(*traj, noise_free(), 1, 10.0);
  const Integrated x = integrate_midpoint(samples, traj->at(traj->t_begin()), -9.81);
  EXPECT_GT((x.p - traj->at(samples.back().t).p_WR).norm(), 10.0);
}

TEST(ImuSynthesis, AccelerometerConventionMatchesRealEurocAtStandstill) {
  const std::string dir = RTSLAM_SOURCE_DIR "/../shared/datasets/euroc-v101-static/mav0/";
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << "dataset " << dir << " not found";
  const Trajectory gt = io::read_trajectory(dir + "state_groundtruth_estimate0/data.csv");
  ASSERT_FALSE(gt.poses.empty());
  const TimeNs t0 = gt.poses.front().t, t1 = t0 + kNsPerSecond;
  // Prediction: our model at rest (a_W = 0, w = 0) applied to the ground-truth attitude, plus the GT accel bias.
  Vector3d predicted = Vector3d::Zero();
  int n_gt = 0;
  for (const StampedPose& p : gt.poses) {
    if (p.t < t0 || p.t >= t1) continue;
    ASSERT_TRUE(p.accel_bias.has_value());
    KinematicState s;
    s.q_WR = p.q_WR.normalized();
    Vector3d gyro, accel;
    ideal_imu(s, 9.81, gyro, accel);
    predicted += accel + *p.accel_bias;
    ++n_gt;
  }
  ASSERT_GE(n_gt, 15);
  predicted /= n_gt;
  // The real accelerometer mean over the same second.
  std::ifstream in(dir + "imu0/data.csv");
  ASSERT_TRUE(in.good());
  std::string line;
  Vector3d measured = Vector3d::Zero();
  int n_imu = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream ss(line);
    long long t;
    double w[3], a[3];
    ss >> t >> w[0] >> w[1] >> w[2] >> a[0] >> a[1] >> a[2];
    if (t < t0 || t >= t1) continue;
    measured += Vector3d(a[0], a[1], a[2]);
    ++n_imu;
  }
  ASSERT_GE(n_imu, 190);
  measured /= n_imu;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(predicted[i], measured[i], 0.05) << "axis " << i;
  // And the opposite convention (R a instead of Rᵀ a) would be far off: the check discriminates.
  KinematicState s;
  s.q_WR = gt.poses.front().q_WR.normalized().conjugate();
  Vector3d gyro, wrong;
  ideal_imu(s, 9.81, gyro, wrong);
  EXPECT_GT((wrong - measured).norm(), 1.0);
}

// A robot at rest: no waves.
std::unique_ptr<ContinuousTrajectory> at_rest(double duration_s) {
  WaveTrajectoryParams p;
  p.duration_s = duration_s;
  return std::make_unique<WaveTrajectory>(p);
}

TEST(ImuSynthesis, WhiteNoiseMatchesTheContinuousDensity) {
  const auto traj = at_rest(60.0);
  ImuSynthOptions opt;
  opt.noise.gyro_random_walk = 0.0;
  opt.noise.accel_random_walk = 0.0;
  const auto s = synthesize(*traj, opt, 42, 50.0);
  Vector3d mg = Vector3d::Zero(), ma = Vector3d::Zero();
  for (const auto& x : s) {
    mg += x.gyro;
    ma += x.accel;
  }
  mg /= s.size();
  ma /= s.size();
  Vector3d vg = Vector3d::Zero(), va = Vector3d::Zero();
  for (const auto& x : s) {
    vg += (x.gyro - mg).cwiseAbs2();
    va += (x.accel - ma).cwiseAbs2();
  }
  vg /= s.size() - 1;
  va /= s.size() - 1;
  const double sg = opt.noise.gyro_noise_density * std::sqrt(opt.rate_hz);
  const double sa = opt.noise.accel_noise_density * std::sqrt(opt.rate_hz);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(std::sqrt(vg[i]), sg, 0.03 * sg);  // 10k samples: std of the std estimate ~0.7 %
    EXPECT_NEAR(std::sqrt(va[i]), sa, 0.03 * sa);
  }
  // At rest the mean specific force is +g along the world vertical seen in the body, plus the bias.
  const Vector3d expected = traj->at(0).q_WR.conjugate() * Vector3d(0, 0, 9.81) + s.front().accel_bias;
  EXPECT_LT((ma - expected).norm(), 0.01);
}

TEST(ImuSynthesis, BiasRandomWalkGrowsWithTheDensity) {
  const auto traj = at_rest(10.0);
  ImuSynthOptions opt;
  opt.noise.gyro_random_walk = 1e-3;
  opt.noise.accel_random_walk = 1e-2;
  const int runs = 300;
  const double T = 4.0;
  double var_g = 0.0, var_a = 0.0;
  for (int r = 0; r < runs; ++r) {
    ImuSynthesizer imu(*traj, opt, Rng(1000 + r));
    const SynthImuSample first = imu.sample(0);
    SynthImuSample last;
    for (TimeNs t = 5'000'000; t <= from_seconds(T); t += 5'000'000) last = imu.sample(t);
    var_g += (last.gyro_bias - first.gyro_bias).squaredNorm() / 3.0;
    var_a += (last.accel_bias - first.accel_bias).squaredNorm() / 3.0;
  }
  var_g /= runs;
  var_a /= runs;
  // 900 squared samples: the variance estimate has ~5 % relative std; allow 15 %.
  EXPECT_NEAR(var_g, 1e-6 * T, 0.15 * 1e-6 * T);
  EXPECT_NEAR(var_a, 1e-4 * T, 0.15 * 1e-4 * T);
}

TEST(ImuSynthesis, SeedsRedrawEveryNoiseSource) {
  const auto traj = make_handheld(1, Vector3d::Zero(), 5.0);
  const ImuSynthOptions opt;
  const auto a = synthesize(*traj, opt, 7, 2.0), a2 = synthesize(*traj, opt, 7, 2.0), b = synthesize(*traj, opt, 8, 2.0);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(a.back().gyro, a2.back().gyro);
  EXPECT_EQ(a.back().accel, a2.back().accel);
  EXPECT_NE(a.front().gyro_bias, b.front().gyro_bias);    // initial biases
  EXPECT_NE(a.front().accel_bias, b.front().accel_bias);
  EXPECT_NE((a.back().gyro - a.back().gyro_bias), (b.back().gyro - b.back().gyro_bias));  // white noise
}

TEST(ImuSynthesis, SaturationClampsEachGyroAxis) {
  const auto traj = make_high_dynamic(3, Vector3d(0, 0, 1.5), 45.0);
  ImuSynthOptions opt = noise_free();
  opt.gyro_saturation_deg_s = 300.0;
  ImuSynthesizer imu(*traj, opt, Rng(1));
  const double lim = 300.0 * std::numbers::pi / 180.0;
  int clamped = 0;
  for (TimeNs t = from_seconds(30.0); t <= from_seconds(45.0); t += 5'000'000) {
    const SynthImuSample s = imu.sample(t);
    EXPECT_LE(s.gyro.cwiseAbs().maxCoeff(), lim + 1e-12);
    if (s.gyro.cwiseAbs().maxCoeff() >= lim - 1e-12) ++clamped;
  }
  EXPECT_GT(clamped, 10);  // the extreme phase exceeds 300 deg/s
}

}  // namespace
}  // namespace rtslam::sim
