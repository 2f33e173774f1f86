#include "rtslam/models/robots/odometry.hpp"

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

Layout pose_layout() { return Layout::euclidean(3).then_quaternion(); }

Vector7d make_state(const Vector3d& p, const Quaterniond& q) {
  Vector7d x;
  x << p, math::quat_to_wxyz(q);
  return x;
}

// Identity, near-identity (series branch of Exp), rotation by π, random poses.
std::vector<Vector7d> sample_odometry_states() {
  Rng rng(17);
  std::vector<Vector7d> out;
  out.push_back(make_state(Vector3d::Zero(), Quaterniond::Identity()));
  out.push_back(make_state(Vector3d(1e-9, 0, 0), math::exp_so3(Vector3d(1e-10, 0, -1e-10))));
  out.push_back(make_state(Vector3d(1, 2, 3), math::exp_so3(Vector3d(0, M_PI, 0))));
  for (int i = 0; i < 5; ++i) out.push_back(make_state(randn_vec<3>(rng, 3.0), math::exp_so3(randn_vec<3>(rng, 1.5))));
  return out;
}

// No motion, tiny motion, a wheel step, a turn by almost π, random increments.
std::vector<OdometryIncrement> sample_inputs() {
  Rng rng(18);
  std::vector<OdometryIncrement> out;
  out.push_back({Vector3d::Zero(), Vector3d::Zero(), 0.01});
  out.push_back({Vector3d(1e-9, -1e-9, 0), Vector3d(0, 1e-10, 1e-10), 0.01});
  out.push_back({Vector3d(0.02, 0, 0), Vector3d(0, 0, 0.01), 0.02});
  out.push_back({Vector3d(0.3, -0.1, 0.05), Vector3d(0, 0, M_PI - 1e-3), 0.5});
  for (int i = 0; i < 4; ++i) out.push_back({randn_vec<3>(rng, 0.5), randn_vec<3>(rng, 0.5), 0.1});
  return out;
}

TEST(Odometry, StateJacobianMatchesNumeric) {
  for (const Vector7d& x : sample_odometry_states()) {
    for (const OdometryIncrement& u : sample_inputs()) {
      Vector7d xo;
      Matrix6d F;
      odometry_predict(x, u, xo, &F);
      const auto f = [&](const VectorXd& xi) {
        Vector7d y;
        odometry_predict(xi, u, y);
        return VectorXd(y);
      };
      EXPECT_TRUE(check_jacobian("F", f, x, F, pose_layout(), pose_layout()));
    }
  }
}

TEST(Odometry, InputJacobianMatchesNumeric) {
  for (const Vector7d& x : sample_odometry_states()) {
    for (const OdometryIncrement& u : sample_inputs()) {
      Vector7d xo;
      Matrix6d G;
      odometry_predict(x, u, xo, nullptr, &G);
      VectorXd u0(6);
      u0 << u.dp, u.dtheta;
      const auto f = [&](const VectorXd& ui) {
        Vector7d y;
        odometry_predict(x, {ui.head<3>(), ui.tail<3>(), u.dt}, y);
        return VectorXd(y);
      };
      EXPECT_TRUE(check_jacobian("G", f, u0, G, Layout::euclidean(6), pose_layout()));
    }
  }
}

TEST(Odometry, MotionComposesThePoseWithTheIncrement) {
  const Vector7d x = sample_odometry_states()[4];
  const OdometryIncrement u = sample_inputs()[5];
  Vector7d xo;
  odometry_predict(x, u, xo);
  const math::Pose T_WR{math::quat_from_wxyz(x.segment<4>(3)), x.head<3>()};
  const math::Pose T_RRn{math::exp_so3(u.dtheta), u.dp};
  const math::Pose T_WRn = math::compose_poses(T_WR, T_RRn);
  EXPECT_LT((xo.head<3>() - T_WRn.p).norm(), 1e-12);
  EXPECT_LT(math::quat_from_wxyz(xo.segment<4>(3)).angularDistance(T_WRn.q), 1e-12);
  EXPECT_NEAR(math::quat_from_wxyz(xo.segment<4>(3)).norm(), 1.0, 1e-14);
}

TEST(Odometry, NoiseSplitsWithTheIncrement) {
  OdometryParams params;
  params.sigma_p = 0.02;
  params.sigma_theta = 0.03;
  params.k_p = 0.1;
  params.k_theta = 0.2;
  const OdometryIncrement u{Vector3d(0.3, 0.4, 0.0), Vector3d(0.0, 0.0, 0.2), 0.1};
  const Matrix6d U = odometry_input_covariance(u, params);
  EXPECT_DOUBLE_EQ(U(0, 0), 0.0004 * 0.1 + 0.01 * 0.5);
  EXPECT_DOUBLE_EQ(U(5, 5), 0.0009 * 0.1 + 0.04 * 0.2);
  EXPECT_DOUBLE_EQ(U(0, 1), 0.0);
  for (double f : {0.0, 0.25, 0.7}) {
    const Matrix6d sum = odometry_input_covariance(u.scaled(f), params) + odometry_input_covariance(u.scaled(1 - f), params);
    EXPECT_LT((sum - U).norm(), 1e-15) << f;
  }
}

TEST(Odometry, SplitIncrementApproachesTheWhole) {
  // Two halves of a small constant-twist increment end where the whole does, to first order in |dθ||dp|.
  const Vector7d x = sample_odometry_states()[3];
  const OdometryIncrement u{Vector3d(0.05, 0.01, 0.0), Vector3d(0.0, 0.0, 0.02), 0.02};
  Vector7d whole, half;
  odometry_predict(x, u, whole);
  odometry_predict(x, u.scaled(0.5), half);
  odometry_predict(half, u.scaled(0.5), half);
  EXPECT_LT((whole.head<3>() - half.head<3>()).norm(), 0.5 * u.dp.norm() * u.dtheta.norm());
  EXPECT_LT(math::quat_from_wxyz(whole.segment<4>(3)).angularDistance(math::quat_from_wxyz(half.segment<4>(3))), 1e-12);
}

TEST(Odometry, ValidateNamesTheKey) {
  OdometryParams p;
  p.k_theta = -1.0;
  try {
    p.validate();
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("odometry/k_theta"), std::string::npos) << e.what();
  }
  p.k_theta = 0.1;
  p.sigma_p = std::nan("");
  EXPECT_THROW(p.validate(), ConfigError);
}

}  // namespace
}  // namespace rtslam::models
