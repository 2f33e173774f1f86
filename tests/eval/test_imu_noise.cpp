// The IMU noise measurement (eval/imu_noise.hpp) on synthetic recordings of known noise: an analytic trajectory, its
// exact IMU readings plus seeded white noise of known density and constant biases, and ground-truth states at 20 Hz.
#include <cmath>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/eval/imu_noise.hpp"
#include "support/temp_dir.hpp"

using namespace rtslam;
using namespace rtslam::eval;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

constexpr double kG = 9.81;

/// f(t) = A (1 − cos ωt)² for t > 0, 0 before: value, first and second derivatives all zero at t = 0, so a motion
/// made of these starts from rest smoothly.
struct Bump {
  double A, w;
  double f(double t) const { return t <= 0 ? 0.0 : A * std::pow(1.0 - std::cos(w * t), 2); }
  double df(double t) const { return t <= 0 ? 0.0 : 2.0 * A * (1.0 - std::cos(w * t)) * w * std::sin(w * t); }
  double ddf(double t) const {
    if (t <= 0) return 0.0;
    const double u = 1.0 - std::cos(w * t), du = w * std::sin(w * t), ddu = w * w * std::cos(w * t);
    return 2.0 * A * (du * du + u * ddu);
  }
};

/// Position and yaw-pitch-roll (R_WR = Rz(a) Ry(b) Rx(c)) made of bumps, at rest until t_rest.
struct Motion {
  Bump px{0.4, 0.9}, py{0.3, 1.3}, pz{0.2, 0.7}, a{0.3, 0.8}, b{0.15, 1.1}, c{0.2, 1.7};
  double t_rest = 0.0;
  Matrix3d R(double t) const {
    const double s = t - t_rest;
    return (Eigen::AngleAxisd(a.f(s), Vector3d::UnitZ()) * Eigen::AngleAxisd(b.f(s), Vector3d::UnitY()) *
            Eigen::AngleAxisd(c.f(s), Vector3d::UnitX()))
        .toRotationMatrix();
  }
  Vector3d p(double t) const {
    const double s = t - t_rest;
    return {px.f(s), py.f(s), 1.0 + pz.f(s)};
  }
  Vector3d v(double t) const {
    const double s = t - t_rest;
    return {px.df(s), py.df(s), pz.df(s)};
  }
  Vector3d acc(double t) const {
    const double s = t - t_rest;
    return {px.ddf(s), py.ddf(s), pz.ddf(s)};
  }
  /// Body rate ω_R: R_WRᵀ Ṙ_WR = [(Ry Rx)ᵀ ȧ z + Rxᵀ ḃ y + ċ x]×.
  Vector3d omega(double t) const {
    const double s = t - t_rest;
    const Matrix3d Rx = Eigen::AngleAxisd(c.f(s), Vector3d::UnitX()).toRotationMatrix();
    const Matrix3d Ry = Eigen::AngleAxisd(b.f(s), Vector3d::UnitY()).toRotationMatrix();
    return (Ry * Rx).transpose() * Vector3d(0, 0, a.df(s)) + Rx.transpose() * Vector3d(0, b.df(s), 0) +
           Vector3d(c.df(s), 0, 0);
  }
};

struct Recording {
  std::vector<io::ImuSample> imu;
  Trajectory states;
};

struct RecordingOptions {
  double duration_s = 200.0;
  double imu_rate_hz = 200.0;
  double state_rate_hz = 20.0;
  double state_offset_s = 0.0;          // states at these instants after IMU sample times
  double gyro_density = 3.4e-4;         // rad/s/√Hz
  double accel_density = 7e-3;          // m/s²/√Hz
  double rest_noise_factor = 1.0;       // noise at rest multiplied by this (a vibrating MAV on the ground)
  double t_rest = 0.0;
  std::uint64_t seed = 7;
};

Recording make_recording(const RecordingOptions& o) {
  Motion m;
  m.t_rest = o.t_rest;
  const Vector3d b_w(0.01, -0.02, 0.005), b_a(0.1, -0.05, 0.2), g_W(0, 0, -kG);
  Rng rng(o.seed);
  Recording r;
  const double dt = 1.0 / o.imu_rate_hz;
  const int n = static_cast<int>(o.duration_s * o.imu_rate_hz);
  for (int i = 0; i <= n; ++i) {
    const double t = i * dt;
    const double k = t < o.t_rest ? o.rest_noise_factor : 1.0;
    io::ImuSample s;
    s.t = from_seconds(t);
    // Discrete white noise of a continuous density σ: std σ/√dt per sample.
    s.gyro = m.omega(t) + b_w + randn_vec<3>(rng, k * o.gyro_density / std::sqrt(dt));
    s.accel = m.R(t).transpose() * (m.acc(t) - g_W) + b_a + randn_vec<3>(rng, k * o.accel_density / std::sqrt(dt));
    r.imu.push_back(s);
  }
  const int n_states = static_cast<int>(std::floor((o.duration_s - o.state_offset_s) * o.state_rate_hz + 1e-9)) + 1;
  for (int k = 0; k < n_states; ++k) {
    const double t = o.state_offset_s + k / o.state_rate_hz;
    StampedPose s;
    s.t = from_seconds(t);
    s.p_WR = m.p(t);
    s.q_WR = Eigen::Quaterniond(m.R(t));
    s.v_WR = m.v(t);
    s.gyro_bias = b_w;
    s.accel_bias = b_a;
    r.states.poses.push_back(s);
  }
  r.states.source = "synthetic";
  return r;
}

std::filesystem::path imu_noise_dir(const std::string& name) {
  return ::rtslam::support::fresh_temp_dir("imu_noise", name);
}

}  // namespace

TEST(ImuNoise, NoiseFreeImuIntegratesToTheStatesBetweenSampleTimes) {
  // States 1.7 ms after IMU samples: both window ends are interpolated.
  const Recording r = make_recording(
      {.duration_s = 30.0, .state_offset_s = 0.0017, .gyro_density = 0.0, .accel_density = 0.0});
  const ImuNoiseReport rep = measure_imu_noise(r.imu, r.states);
  ASSERT_EQ(rep.windows.size(), 3u);
  for (const ImuNoiseWindow& w : rep.windows) {
    EXPECT_GT(w.all.windows, 0) << w.window_s;
    // The midpoint rule's and the interpolation's errors only: 30 to 300 times below the densities tested below.
    EXPECT_LT(w.all.gyro_density, 1e-5) << w.window_s;
    EXPECT_LT(w.all.accel_density, 2e-5) << w.window_s;
  }
}

TEST(ImuNoise, RecoversTheWhiteNoiseDensitiesOfASeededImu) {
  const Recording r = make_recording({});
  const ImuNoiseReport rep = measure_imu_noise(r.imu, r.states);
  for (const ImuNoiseWindow& w : rep.windows) {
    // The midpoint rule averages consecutive samples: variance σ² (T − dt/2), 2.5 % low in density at 50 ms.
    EXPECT_NEAR(w.all.gyro_density / 3.4e-4, 1.0, 0.1) << w.window_s;
    EXPECT_NEAR(w.all.accel_density / 7e-3, 1.0, 0.1) << w.window_s;
    EXPECT_LT(w.all.mean_velocity_residual.norm(), 3.0 * 7e-3 * std::sqrt(w.window_s)) << "biases subtracted";
  }
  EXPECT_EQ(rep.windows[0].all.windows, 200 * 20) << "one window per state but the last";
  ASSERT_TRUE(rep.suggestion);
  EXPECT_NEAR(rep.suggestion->gyroscope_noise_density / 3.4e-4, 1.0, 0.1);
  EXPECT_NEAR(rep.suggestion->accelerometer_noise_density / 7e-3, 1.0, 0.1);
}

TEST(ImuNoise, WrongBiasesShowAsResidualsGrowingWithTheWindow) {
  Recording r = make_recording({.duration_s = 30.0, .gyro_density = 0.0, .accel_density = 0.0});
  for (StampedPose& s : r.states.poses) *s.accel_bias += Vector3d(0.05, 0, 0);  // 0.05 m/s² off
  const ImuNoiseReport rep = measure_imu_noise(r.imu, r.states);
  // δv = 0.05 T: density 0.05 √T / √3 per axis.
  EXPECT_NEAR(rep.windows[2].all.accel_density, 0.05 / std::sqrt(3.0), 0.003);
  EXPECT_NEAR(rep.windows[0].all.accel_density, 0.05 * std::sqrt(0.05 / 3.0), 0.001);
}

TEST(ImuNoise, RestAndFlightAreSplitByTheGroundTruthSpeed) {
  // 20 s at rest with three times the noise (vibration), then 120 s of motion.
  const Recording r = make_recording({.duration_s = 140.0, .rest_noise_factor = 3.0, .t_rest = 20.0});
  const ImuNoiseReport rep = measure_imu_noise(r.imu, r.states);
  ASSERT_TRUE(rep.rest_and_flight);
  const ImuNoiseWindow& w = rep.windows[0];
  EXPECT_GT(w.rest.windows, 350);
  EXPECT_GT(w.flight.windows, 2300);
  EXPECT_NEAR(w.rest.gyro_density / (3.0 * 3.4e-4), 1.0, 0.1);
  EXPECT_NEAR(w.rest.accel_density / (3.0 * 7e-3), 1.0, 0.1);
  EXPECT_NEAR(w.flight.gyro_density / 3.4e-4, 1.0, 0.1);
  EXPECT_NEAR(w.flight.accel_density / 7e-3, 1.0, 0.1);
  ASSERT_TRUE(rep.suggestion);
  EXPECT_NE(rep.suggestion->basis.find("in-flight"), std::string::npos);
  EXPECT_NEAR(rep.suggestion->accelerometer_noise_density / 7e-3, 1.0, 0.1) << "in flight, not the vibration";
  const std::string text = format_imu_noise(rep);
  EXPECT_NE(text.find("at rest"), std::string::npos) << text;
  EXPECT_NE(text.find("gyroscope_noise_density:"), std::string::npos) << text;
  const nlohmann::json j = to_json(rep);
  EXPECT_EQ(j["windows"][0]["flight"]["windows"].get<int>(), w.flight.windows);
}

TEST(ImuNoise, FromAndToSelectTheWindows) {
  const Recording r = make_recording({.duration_s = 30.0});
  ImuNoiseOptions o;
  o.windows_s = {0.05};
  o.from_s = 10.0;
  o.to_s = 20.0;
  const ImuNoiseReport rep = measure_imu_noise(r.imu, r.states, o);
  EXPECT_EQ(rep.states, 201);
  EXPECT_EQ(rep.windows[0].all.windows, 200);
  EXPECT_NEAR(rep.span_s, 10.0, 1e-6);
}

TEST(ImuNoise, WindowsOverAnImuGapAreSkipped) {
  Recording r = make_recording({.duration_s = 30.0});
  // Drop 0.1 s of samples at 10 s.
  std::erase_if(r.imu, [](const io::ImuSample& s) { return s.t > from_seconds(10.0) && s.t < from_seconds(10.1); });
  ImuNoiseOptions o;
  o.windows_s = {0.05};
  const ImuNoiseReport rep = measure_imu_noise(r.imu, r.states, o);
  EXPECT_EQ(rep.windows[0].skipped_gaps, 2);
  EXPECT_NEAR(rep.windows[0].all.accel_density / 7e-3, 1.0, 0.15);
}

TEST(ImuNoise, StatesWithoutVelocityOrNoOverlapAreDataErrors) {
  Recording r = make_recording({.duration_s = 5.0});
  Recording no_v = r;
  no_v.states.poses[3].v_WR.reset();
  try {
    measure_imu_noise(no_v.imu, no_v.states);
    FAIL() << "expected DataError";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("velocity"), std::string::npos) << e.what();
  }
  for (StampedPose& s : r.states.poses) s.t += from_seconds(100.0);
  EXPECT_THROW(measure_imu_noise(r.imu, r.states), DataError);
  ImuNoiseOptions bad;
  bad.windows_s = {-1.0};
  EXPECT_THROW(measure_imu_noise(r.imu, r.states, bad), ConfigError);
}

TEST(ImuNoise, MissingGroundTruthFileIsAnIoErrorNamingIt) {
  const auto d = imu_noise_dir("nogt");
  std::filesystem::create_directories(d / "mav0" / "imu0");
  std::ofstream(d / "mav0" / "imu0" / "data.csv") << "#t,wx,wy,wz,ax,ay,az\n0,0,0,0,0,0,9.81\n";
  try {
    read_imu_noise_input("euroc:" + d.string());
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("state_groundtruth_estimate0/data.csv"), std::string::npos) << e.what();
  }
  EXPECT_THROW(read_imu_noise_input("tum:" + d.string()), ConfigError);
  EXPECT_THROW(read_imu_noise_input((d / "absent").string()), IoError);
  std::filesystem::remove_all(d);
}
