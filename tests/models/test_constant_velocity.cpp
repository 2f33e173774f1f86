#include "rtslam/models/robots/constant_velocity.hpp"

#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/math/rotation.hpp"
#include "support/jacobian_check.hpp"

namespace rtslam::models {
namespace {

using Eigen::Quaterniond;
using Eigen::Vector3d;
using Eigen::VectorXd;
using test::check_jacobian;
using test::Layout;

Layout cv_layout() { return Layout::euclidean(3).then_quaternion().then_euclidean(6); }

Vector13d make_state(const Vector3d& p, const Quaterniond& q, const Vector3d& v, const Vector3d& w) {
  Vector13d x;
  x << p, math::quat_to_wxyz(q), v, w;
  return x;
}

// Identity at rest, near-identity, tiny rates (series branch of Exp), rotation by π, fast spins, random states.
std::vector<Vector13d> sample_states() {
  Rng rng(31);
  std::vector<Vector13d> out;
  out.push_back(make_state(Vector3d::Zero(), Quaterniond::Identity(), Vector3d::Zero(), Vector3d::Zero()));
  out.push_back(make_state(Vector3d(1e-9, 0, 0), math::exp_so3(Vector3d(1e-10, 0, -1e-10)), Vector3d(1e-9, 2e-9, 0),
                           Vector3d(1e-9, -1e-9, 2e-9)));
  out.push_back(make_state(Vector3d(1, 2, 3), math::exp_so3(Vector3d(0, M_PI, 0)), Vector3d(0.5, -0.2, 0.1),
                           Vector3d(0.3, 0.1, -0.2)));
  out.push_back(make_state(Vector3d(-1, 0, 2), math::exp_so3(Vector3d(0.2, 0.3, -0.4)), Vector3d(2, 0, 0),
                           Vector3d(0.0, 0.0, 3.0)));
  for (int i = 0; i < 6; ++i) {
    out.push_back(make_state(randn_vec<3>(rng, 3.0), math::exp_so3(randn_vec<3>(rng, 1.5)), randn_vec<3>(rng, 1.0),
                             randn_vec<3>(rng, 1.0)));
  }
  return out;
}

TEST(ConstantVelocity, TransitionJacobianMatchesNumeric) {
  const ConstantVelocityParams params;
  for (const Vector13d& x : sample_states()) {
    for (double dt : {0.0, 1e-3, 0.033, 0.5}) {
      Vector13d xo;
      Matrix12d F;
      constant_velocity_predict(x, dt, params, xo, &F);
      const auto f = [&](const VectorXd& xi) {
        Vector13d y;
        constant_velocity_predict(xi, dt, params, y);
        return VectorXd(y);
      };
      EXPECT_TRUE(check_jacobian("F dt=" + std::to_string(dt), f, x, F, cv_layout(), cv_layout()));
    }
  }
}

TEST(ConstantVelocity, NoiseCovarianceIsDensityTimesDt) {
  ConstantVelocityParams params;
  params.sigma_v = 0.7;
  params.sigma_w = 1.3;
  const Vector13d x = sample_states()[3];
  for (double dt : {1e-3, 0.05, 0.2}) {
    Vector13d xo;
    Matrix12d Q;
    constant_velocity_predict(x, dt, params, xo, nullptr, &Q);
    for (int i = 0; i < 12; ++i) {
      for (int j = 0; j < 12; ++j) {
        double expected = 0.0;
        if (i == j && i >= 6 && i < 9) expected = 0.49 * dt;
        if (i == j && i >= 9) expected = 1.69 * dt;
        EXPECT_DOUBLE_EQ(Q(i, j), expected) << i << "," << j << " dt " << dt;
      }
    }
    // Linear growth: two steps of dt carry the variance of one step of 2 dt.
    Matrix12d Q2;
    constant_velocity_predict(x, 2 * dt, params, xo, nullptr, &Q2);
    EXPECT_LT((Q2 - 2.0 * Q).norm(), 1e-15);
  }
}

TEST(ConstantVelocity, NoiseMatchesASampledContinuousPerturbation) {
  // The model's v⁺ = v + n_v is the integral of white noise of density σ over dt: simulate it as many small
  // independent increments and compare the sample variance with Q.
  ConstantVelocityParams params;
  params.sigma_v = 1.5;
  params.sigma_w = 0.4;
  const double dt = 0.1;
  const int substeps = 20;
  const int runs = 20000;
  Rng rng(33);
  Eigen::Matrix<double, 6, 6> S = Eigen::Matrix<double, 6, 6>::Zero();
  for (int r = 0; r < runs; ++r) {
    Eigen::Matrix<double, 6, 1> n = Eigen::Matrix<double, 6, 1>::Zero();
    for (int k = 0; k < substeps; ++k) {
      n.head<3>() += randn_vec<3>(rng, params.sigma_v * std::sqrt(dt / substeps));
      n.tail<3>() += randn_vec<3>(rng, params.sigma_w * std::sqrt(dt / substeps));
    }
    S += n * n.transpose();
  }
  S /= runs;
  Vector13d xo;
  Matrix12d Q;
  constant_velocity_predict(sample_states()[0], dt, params, xo, nullptr, &Q);
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(S(i, i), Q(6 + i, 6 + i), 0.05 * Q(6 + i, 6 + i)) << i;
  }
}

TEST(ConstantVelocity, ZeroDtIsIdentity) {
  const ConstantVelocityParams params;
  for (const Vector13d& x : sample_states()) {
    Vector13d xo;
    Matrix12d F;
    Matrix12d Q;
    constant_velocity_predict(x, 0.0, params, xo, &F, &Q);
    EXPECT_LT((xo - x).norm(), 1e-15);
    EXPECT_TRUE(F.isIdentity(1e-15));
    EXPECT_TRUE(Q.isZero(0.0));
  }
}

TEST(ConstantVelocity, IntegratesAKnownMotionInTheRobotFrame) {
  // Start rolled by 90° about x, spin about the BODY z axis at 0.5 rad/s and move at constant world velocity.
  const Quaterniond q0 = math::exp_so3(Vector3d(M_PI / 2, 0, 0));
  const Vector3d v(0.3, -0.1, 0.2);
  const Vector3d w(0.0, 0.0, 0.5);
  Vector13d x = make_state(Vector3d(1, 1, 1), q0, v, w);
  const ConstantVelocityParams params;
  for (int k = 0; k < 100; ++k) constant_velocity_predict(x, 0.02, params, x);  // x aliases x_out
  const Quaterniond expected = q0 * Quaterniond(Eigen::AngleAxisd(1.0, Vector3d::UnitZ()));
  EXPECT_LT(math::boxminus(math::quat_from_wxyz(x.segment<4>(3)), expected).norm(), 1e-12);
  EXPECT_LT((x.head<3>() - (Vector3d(1, 1, 1) + 2.0 * v)).norm(), 1e-12);
  EXPECT_EQ(x.segment<3>(7), v);
  EXPECT_EQ(x.tail<3>(), w);
  EXPECT_NEAR(x.segment<4>(3).norm(), 1.0, 1e-15);
  // The body z axis is the world −y axis after the 90° roll, and stays so: spinning about it keeps it fixed.
  const Vector3d z_W = math::quat_from_wxyz(x.segment<4>(3)) * Vector3d::UnitZ();
  EXPECT_LT((z_W - Vector3d(0, -1, 0)).norm(), 1e-12);
}

TEST(ConstantVelocity, AliasedOutputMatchesSeparateOutput) {
  const ConstantVelocityParams params;
  for (const Vector13d& x : sample_states()) {
    Vector13d separate;
    constant_velocity_predict(x, 0.1, params, separate);
    Vector13d aliased = x;
    constant_velocity_predict(aliased, 0.1, params, aliased);
    EXPECT_EQ(aliased, separate);
  }
}

TEST(ConstantVelocity, ParamsValidationNamesTheValue) {
  ConstantVelocityParams p;
  EXPECT_NO_THROW(p.validate());
  p.sigma_w = -1.0;
  try {
    p.validate();
    ADD_FAILURE() << "negative sigma_w accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("sigma_w = -1"), std::string::npos) << e.what();
  }
  p.sigma_w = 1.0;
  p.sigma_v = std::nan("");
  EXPECT_THROW(p.validate(), ConfigError);
}

}  // namespace
}  // namespace rtslam::models
