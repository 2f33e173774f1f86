#include "rtslam/models/robots/inertial.hpp"

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/math/rotation.hpp"
#include "support/jacobian_check.hpp"

namespace rtslam::models {
namespace {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;
using Eigen::VectorXd;
using test::check_jacobian;
using test::Layout;

Layout state_layout() { return Layout::euclidean(3).then_quaternion().then_euclidean(12); }

Vector19d make_state(const Vector3d& p, const Quaterniond& q, const Vector3d& v, const Vector3d& a_b,
                     const Vector3d& w_b, const Vector3d& g) {
  Vector19d x;
  x << p, math::quat_to_wxyz(q), v, a_b, w_b, g;
  return x;
}

struct StepCase {
  Vector19d x;
  ImuMeasurement k, k1;
};

// Identity at rest, tiny rates (series branch of Exp), rotations by π, fast spins and random states and samples.
std::vector<StepCase> sample_cases() {
  Rng rng(41);
  const Vector3d g(0, 0, -9.81);
  std::vector<StepCase> out;
  StepCase c;
  c.x = make_state(Vector3d::Zero(), Quaterniond::Identity(), Vector3d::Zero(), Vector3d::Zero(), Vector3d::Zero(), g);
  c.k.accel = c.k1.accel = Vector3d(0, 0, 9.81);
  out.push_back(c);
  c.x = make_state(Vector3d(1e-9, 0, 0), math::exp_so3(Vector3d(1e-10, 0, 0)), Vector3d(1e-9, 0, 0),
                   Vector3d(1e-3, 0, 0), Vector3d(1e-9, 0, 1e-9), g);
  c.k.gyro = Vector3d(1e-9, -1e-9, 0);
  c.k1.gyro = Vector3d(2e-9, 0, 1e-9);
  out.push_back(c);
  c.x = make_state(Vector3d(1, 2, 3), math::exp_so3(Vector3d(M_PI, 0, 0)), Vector3d(0.5, -1, 0.2),
                   Vector3d(0.1, -0.05, 0.02), Vector3d(0.01, 0.02, -0.01), g);
  c.k.accel = Vector3d(0.3, -0.2, -9.7);
  c.k1.accel = Vector3d(0.5, 0.1, -9.9);
  c.k.gyro = Vector3d(3.0, -1.0, 2.0);
  c.k1.gyro = Vector3d(3.5, -0.5, 1.0);
  out.push_back(c);
  for (int i = 0; i < 6; ++i) {
    c.x = make_state(randn_vec<3>(rng, 3.0), math::exp_so3(randn_vec<3>(rng, 1.5)), randn_vec<3>(rng, 1.0),
                     randn_vec<3>(rng, 0.1), randn_vec<3>(rng, 0.02), g + randn_vec<3>(rng, 0.1));
    c.k.accel = randn_vec<3>(rng, 5.0);
    c.k1.accel = c.k.accel + randn_vec<3>(rng, 1.0);
    c.k.gyro = randn_vec<3>(rng, 1.0);
    c.k1.gyro = c.k.gyro + randn_vec<3>(rng, 0.3);
    out.push_back(c);
  }
  return out;
}

TEST(Inertial, TransitionJacobianMatchesNumeric) {
  for (const StepCase& c : sample_cases()) {
    for (double dt : {0.0, 0.005, 0.05}) {
      Vector19d xo;
      Matrix18d F;
      const InertialParams params;
      inertial_predict(c.x, c.k, c.k1, dt, params, xo, &F);
      const auto f = [&](const VectorXd& xi) {
        Vector19d y;
        inertial_predict(xi, c.k, c.k1, dt, params, y);
        return VectorXd(y);
      };
      EXPECT_TRUE(check_jacobian("F dt=" + std::to_string(dt), f, c.x, F, state_layout(), state_layout()));
    }
  }
}

TEST(Inertial, NoiseJacobianMatchesNumeric) {
  Rng rng(43);
  for (const StepCase& c : sample_cases()) {
    for (double dt : {0.005, 0.05}) {
      // At zero noise (the mean prediction) and at a non-zero noise sample.
      for (const Vector12d& n : {Vector12d::Zero().eval(), (randn_vec<12>(rng, 1e-2)).eval()}) {
        Vector19d xo;
        Matrix18x12d G;
        Matrix18d F;
        inertial_step(c.x, c.k, c.k1, dt, n, xo, &F, &G);
        const auto f = [&](const VectorXd& ni) {
          Vector19d y;
          inertial_step(c.x, c.k, c.k1, dt, ni, y);
          return VectorXd(y);
        };
        EXPECT_TRUE(check_jacobian("G", f, n, G, Layout::euclidean(12), state_layout()));
        const auto fx = [&](const VectorXd& xi) {
          Vector19d y;
          inertial_step(xi, c.k, c.k1, dt, n, y);
          return VectorXd(y);
        };
        EXPECT_TRUE(check_jacobian("F at noise", fx, c.x, F, state_layout(), state_layout()));
      }
    }
  }
}

TEST(Inertial, NoiseCovarianceIsMappedDensityTimesDt) {
  InertialParams params;
  params.accelerometer_noise_density = 0.02;
  params.gyroscope_noise_density = 0.003;
  params.accelerometer_random_walk = 0.01;
  params.gyroscope_random_walk = 0.001;
  const StepCase c = sample_cases()[3];
  for (double dt : {0.005, 0.02}) {
    Vector19d xo;
    Matrix18d Q;
    inertial_predict(c.x, c.k, c.k1, dt, params, xo, nullptr, &Q);
    Matrix18x12d G;
    inertial_step(c.x, c.k, c.k1, dt, Vector12d::Zero(), xo, nullptr, &G);
    EXPECT_TRUE(Q.isApprox(Q.transpose(), 0.0));
    // Bias rows: σ² dt exactly, uncorrelated with the rest.
    EXPECT_TRUE((Q.block<3, 3>(9, 9).isApprox(1e-4 * dt * Matrix3d::Identity(), 1e-14)));
    EXPECT_TRUE((Q.block<3, 3>(12, 12).isApprox(1e-6 * dt * Matrix3d::Identity(), 1e-14)));
    EXPECT_TRUE((Q.block<6, 9>(9, 0).isZero(0.0)));
    EXPECT_TRUE((Q.block<3, 18>(15, 0).isZero(0.0)));  // gravity is constant
    // Attitude: Jr σ_g² dt Jrᵀ ≈ σ_g² dt I for small steps; velocity: σ_a² dt plus the attitude noise mapped
    // through ½ R⁺ [a − a_b]× Jr dt.
    EXPECT_NEAR(Q(3, 3), 9e-6 * dt, 1e-3 * 9e-6 * dt);
    EXPECT_GT(Q(6, 6), 4e-4 * dt);
    const double lever = 0.5 * dt * (c.k1.accel - c.x.segment<3>(10)).norm();
    EXPECT_LT(Q(6, 6), (4e-4 + lever * lever * 9e-6) * dt * (1 + 1e-9));
    // Sampling the noise and propagating it through the (nonlinear) step reproduces Q to first order.
    Rng rng(47);
    Vector12d sd;
    sd << Vector3d::Constant(0.003 * std::sqrt(dt)), Vector3d::Constant(0.02 * std::sqrt(dt)),
        Vector3d::Constant(0.01 * std::sqrt(dt)), Vector3d::Constant(0.001 * std::sqrt(dt));
    Matrix18d S = Matrix18d::Zero();
    const int runs = 20000;
    for (int r = 0; r < runs; ++r) {
      Vector12d n;
      for (int i = 0; i < 12; ++i) n[i] = sd[i] * randn(rng);
      Vector19d y;
      inertial_step(c.x, c.k, c.k1, dt, n, y);
      const VectorXd e = state_layout().minus(y, xo);
      S += e * e.transpose();
    }
    S /= runs;
    for (int i = 3; i < 15; ++i) EXPECT_NEAR(S(i, i), Q(i, i), 0.05 * Q(i, i)) << i << " dt " << dt;
  }
}

TEST(Inertial, ZeroDtIsIdentity) {
  for (const StepCase& c : sample_cases()) {
    Vector19d xo;
    Matrix18d F;
    Matrix18d Q;
    inertial_predict(c.x, c.k, c.k1, 0.0, InertialParams{}, xo, &F, &Q);
    EXPECT_LT((xo - c.x).norm(), 1e-15);
    EXPECT_TRUE(F.isIdentity(1e-15));
    EXPECT_TRUE(Q.isZero(0.0));
  }
}

TEST(Inertial, StaysAtRestWithTiltedBodyAndBiases) {
  // EuRoC-like: the IMU x axis ~22° off vertical; biases present in the readings and known to the state.
  const Quaterniond q = math::exp_so3(Vector3d(0.1, 1.2, -0.4));
  const Vector3d g(0, 0, -9.81);
  const Vector3d a_b(0.05, -0.02, 0.1);
  const Vector3d w_b(0.002, -0.001, 0.003);
  ImuMeasurement m;
  m.accel = -(q.conjugate() * g) + a_b;
  m.gyro = w_b;
  Vector19d x = make_state(Vector3d(1, 2, 3), q, Vector3d::Zero(), a_b, w_b, g);
  const Vector19d x0 = x;
  for (int k = 0; k < 2000; ++k) inertial_predict(x, m, m, 0.005, InertialParams{}, x);  // 10 s, aliased
  EXPECT_LT((x.head<3>() - x0.head<3>()).norm(), 1e-9);
  EXPECT_LT(x.segment<3>(7).norm(), 1e-10);
  EXPECT_LT(math::boxminus(math::quat_from_wxyz(x.segment<4>(3)), q).norm(), 1e-12);
}

// A smooth analytic trajectory with derivatives written out by hand: position sinusoids and ZYX Euler angles
// (yaw ψ, pitch ϑ, roll φ) that are sinusoids too; q_WR = Rz(ψ) Ry(ϑ) Rx(φ).
struct AnalyticMotion {
  static constexpr double kW = 0.8;  // rad/s
  static Vector3d p(double t) {
    return Vector3d(2.0 * std::sin(kW * t), 1.5 * std::cos(1.3 * kW * t), 0.5 * std::sin(2 * kW * t));
  }
  static Vector3d v(double t) {
    return Vector3d(2.0 * kW * std::cos(kW * t), -1.5 * 1.3 * kW * std::sin(1.3 * kW * t), kW * std::cos(2 * kW * t));
  }
  static Vector3d a(double t) {
    return Vector3d(-2.0 * kW * kW * std::sin(kW * t), -1.5 * 1.69 * kW * kW * std::cos(1.3 * kW * t),
                    -2.0 * kW * kW * std::sin(2 * kW * t));
  }
  // Euler angles and rates.
  static Vector3d e(double t) {
    return Vector3d(0.9 * std::sin(0.7 * t), 0.3 * std::sin(1.1 * t), 0.4 * std::cos(0.9 * t));
  }
  static Vector3d de(double t) {
    return Vector3d(0.63 * std::cos(0.7 * t), 0.33 * std::cos(1.1 * t), -0.36 * std::sin(0.9 * t));
  }
  static Quaterniond q(double t) {
    const Vector3d a = e(t);
    return Quaterniond(Eigen::AngleAxisd(a[0], Vector3d::UnitZ())) *
           Quaterniond(Eigen::AngleAxisd(a[1], Vector3d::UnitY())) *
           Quaterniond(Eigen::AngleAxisd(a[2], Vector3d::UnitX()));
  }
  // Body rate of R = Rz Ry Rx: ω_R = Rxᵀ Ryᵀ (0,0,ψ̇) + Rxᵀ (0,ϑ̇,0) + (φ̇,0,0).
  static Vector3d w(double t) {
    const Vector3d a = e(t);
    const Vector3d d = de(t);
    const Matrix3d Ry = Eigen::AngleAxisd(a[1], Vector3d::UnitY()).toRotationMatrix();
    const Matrix3d Rx = Eigen::AngleAxisd(a[2], Vector3d::UnitX()).toRotationMatrix();
    return Rx.transpose() * Ry.transpose() * Vector3d(0, 0, d[0]) + Rx.transpose() * Vector3d(0, d[1], 0) +
           Vector3d(d[2], 0, 0);
  }
};

struct IntegrationError {
  double p, v, th;
};

// hold_sample: the wrong scheme MATH.md warns about (sample k held over [t_k, t_k+1]), for comparison.
IntegrationError integrate_analytic(double rate_hz, double duration, bool hold_sample = false) {
  const Vector3d g(0, 0, -9.81);
  const Vector3d a_b(0.1, -0.2, 0.05);
  const Vector3d w_b(0.01, 0.02, -0.015);
  const auto imu = [&](double t) {
    ImuMeasurement m;
    m.accel = AnalyticMotion::q(t).conjugate() * (AnalyticMotion::a(t) - g) + a_b;
    m.gyro = AnalyticMotion::w(t) + w_b;
    return m;
  };
  Vector19d x = make_state(AnalyticMotion::p(0), AnalyticMotion::q(0), AnalyticMotion::v(0), a_b, w_b, g);
  const int n = static_cast<int>(std::lround(duration * rate_hz));
  const double dt = 1.0 / rate_hz;
  ImuMeasurement prev = imu(0.0);
  for (int k = 0; k < n; ++k) {
    const ImuMeasurement next = imu((k + 1) * dt);
    inertial_predict(x, prev, hold_sample ? prev : next, dt, InertialParams{}, x);
    prev = next;
  }
  const double t = n * dt;
  return {(x.head<3>() - AnalyticMotion::p(t)).norm(), (x.segment<3>(7) - AnalyticMotion::v(t)).norm(),
          math::boxminus(math::quat_from_wxyz(x.segment<4>(3)), AnalyticMotion::q(t)).norm()};
}

TEST(Inertial, AnalyticMotionDerivativesMatchFiniteDifferences) {
  // Guards the hand-derived body rate used below: q(t+h) ≈ q(t) ⊗ Exp(ω_R h).
  for (double t : {0.0, 1.3, 4.2}) {
    const double h = 1e-6;
    const Vector3d num = math::boxminus(AnalyticMotion::q(t + h), AnalyticMotion::q(t - h)) / (2 * h);
    EXPECT_LT((num - AnalyticMotion::w(t)).norm(), 1e-8);
    const Vector3d vnum = (AnalyticMotion::p(t + h) - AnalyticMotion::p(t - h)) / (2 * h);
    EXPECT_LT((vnum - AnalyticMotion::v(t)).norm(), 1e-8);
    const Vector3d anum = (AnalyticMotion::v(t + h) - AnalyticMotion::v(t - h)) / (2 * h);
    EXPECT_LT((anum - AnalyticMotion::a(t)).norm(), 1e-8);
  }
}

TEST(Inertial, NoiseFreeSamplesOfAnAnalyticMotionReproduceIt) {
  // 10 s of a 3D sinusoidal motion at 200 Hz with biases: the midpoint rule is second order, so the error is
  // small and shrinks ~4x when the rate doubles.
  const IntegrationError e200 = integrate_analytic(200.0, 10.0);
  const IntegrationError e400 = integrate_analytic(400.0, 10.0);
  EXPECT_LT(e200.p, 5e-3) << "position error after 10 s";
  EXPECT_LT(e200.v, 2e-3);
  EXPECT_LT(e200.th, 1e-4);
  EXPECT_GT(e200.p / e400.p, 3.0);
  EXPECT_LT(e200.p / e400.p, 5.0);
  EXPECT_GT(e200.th / e400.th, 3.0);
  // Holding one sample over the interval is first order and far worse.
  const IntegrationError held = integrate_analytic(200.0, 10.0, true);
  EXPECT_GT(held.p, 10.0 * e200.p);
  RecordProperty("position_error_200hz_m", std::to_string(e200.p));
  std::printf(
      "10 s analytic motion: |dp| %.3g m, |dv| %.3g m/s, |dθ| %.3g rad at 200 Hz; |dp| %.3g m at 400 Hz; "
      "holding samples: |dp| %.3g m\n",
      e200.p, e200.v, e200.th, e400.p, held.p);
}

TEST(Inertial, ParamsValidationNamesTheKey) {
  InertialParams p;
  EXPECT_NO_THROW(p.validate());
  p.gyroscope_random_walk = -1.0;
  try {
    p.validate();
    ADD_FAILURE() << "negative random walk accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("gyroscope_random_walk = -1"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rtslam::models
