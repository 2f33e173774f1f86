#include "rtslam/math/rotation.hpp"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "rtslam/core/random.hpp"
#include "support/jacobian_check.hpp"

namespace rtslam::math {
namespace {

using test::check_jacobian;
using test::JacobianCheckOptions;
using test::Layout;
using Eigen::MatrixXd;
using Eigen::VectorXd;

// Rotation vectors covering identity, near-identity (below and above the series threshold), random, near π and π.
std::vector<Vector3d> test_angles() {
  Rng rng(7);
  std::vector<Vector3d> out = {Vector3d::Zero(), Vector3d(1e-10, -2e-10, 3e-11), Vector3d(1e-7, 2e-7, -1e-7),
                               Vector3d(1e-4, -3e-4, 2e-4), Vector3d(0.0, 0.0, M_PI),
                               Vector3d(1.0, 1.0, 1.0).normalized() * (M_PI - 1e-6)};
  for (int i = 0; i < 10; ++i) out.push_back(randn_vec<3>(rng, 1.0));
  return out;
}

Quaterniond random_quat(Rng& rng) { return exp_so3(randn_vec<3>(rng, 1.5)); }

TEST(Rotation, ExpMatchesAngleAxisAndLogInvertsIt) {
  for (const Vector3d& th : test_angles()) {
    const Quaterniond q = exp_so3(th);
    const double a = th.norm();
    const Quaterniond ref = a > 0 ? Quaterniond(Eigen::AngleAxisd(a, th / a)) : Quaterniond::Identity();
    EXPECT_LT((q.toRotationMatrix() - ref.toRotationMatrix()).norm(), 1e-12) << th.transpose();
    EXPECT_NEAR(q.norm(), 1.0, 1e-15);
    const Vector3d back = log_so3(q);
    if (a < M_PI - 1e-3) {
      EXPECT_LT((back - th).norm(), 1e-12 * std::max(1.0, a)) << th.transpose();
    } else {
      // At π, θ and −θ are the same rotation: compare rotations.
      EXPECT_LT((exp_so3(back).toRotationMatrix() - q.toRotationMatrix()).norm(), 1e-9);
    }
  }
}

TEST(Rotation, LogKeepsNonNegativeScalarBranch) {
  const Quaterniond q = exp_so3(Vector3d(0.3, -0.2, 0.1));
  Quaterniond neg = q;
  neg.coeffs() = -q.coeffs();
  EXPECT_LT((log_so3(neg) - log_so3(q)).norm(), 1e-14);
}

TEST(Rotation, WxyzConversionIsExplicit) {
  const Vector4d wxyz(0.5, 0.5, -0.5, 0.5);
  const Quaterniond q = quat_from_wxyz(wxyz);
  EXPECT_EQ(q.w(), 0.5);
  EXPECT_EQ(q.y(), -0.5);
  EXPECT_EQ(quat_to_wxyz(q), wxyz);
}

TEST(Rotation, ExpJacobianIsRightJacobian) {
  for (const Vector3d& th : test_angles()) {
    if (th.norm() > M_PI - 1e-3) continue;  // Log's branch cut: the output tangent is discontinuous there
    Matrix3d J;
    exp_so3(th, &J);
    const auto f = [](const VectorXd& x) { return VectorXd(quat_to_wxyz(exp_so3(x.head<3>()))); };
    EXPECT_TRUE(check_jacobian("J_q_theta", f, th, J, Layout::euclidean(3), Layout::quaternion()));
  }
}

TEST(Rotation, LogJacobianIsInverseRightJacobian) {
  for (const Vector3d& th : test_angles()) {
    if (th.norm() > M_PI - 1e-3) continue;
    const Quaterniond q = exp_so3(th);
    Matrix3d J;
    log_so3(q, &J);
    const auto f = [](const VectorXd& x) { return VectorXd(log_so3(quat_from_wxyz(x.head<4>()))); };
    EXPECT_TRUE(check_jacobian("J_theta_q", f, quat_to_wxyz(q), J, Layout::quaternion(), Layout::euclidean(3)));
  }
}

TEST(Rotation, RightJacobianInverseIsInverse) {
  for (const Vector3d& th : test_angles()) {
    if (th.norm() > M_PI - 1e-3) continue;
    EXPECT_LT((right_jacobian(th) * right_jacobian_inverse(th) - Matrix3d::Identity()).norm(), 1e-9);
  }
}

TEST(Rotation, RotateJacobiansMatchNumeric) {
  Rng rng(11);
  for (const Vector3d& th : test_angles()) {
    const Quaterniond q = exp_so3(th);
    const Vector3d v = randn_vec<3>(rng, 2.0);
    VectorXd x(7);
    x << quat_to_wxyz(q), v;
    const Layout in = Layout::quaternion().then_euclidean(3);
    Matrix3d Jq;
    Matrix3d Jv;
    rotate(q, v, &Jq, &Jv);
    MatrixXd J(3, 6);
    J << Jq, Jv;
    const auto f = [](const VectorXd& x) { return VectorXd(rotate(quat_from_wxyz(x.head<4>()), x.tail<3>())); };
    EXPECT_TRUE(check_jacobian("rotate", f, x, J, in, Layout::euclidean(3)));

    rotate_inverse(q, v, &Jq, &Jv);
    J << Jq, Jv;
    const auto g = [](const VectorXd& x) {
      return VectorXd(rotate_inverse(quat_from_wxyz(x.head<4>()), x.tail<3>()));
    };
    EXPECT_TRUE(check_jacobian("rotate_inverse", g, x, J, in, Layout::euclidean(3)));
  }
}

TEST(Rotation, ComposeAndInverseJacobiansMatchNumeric) {
  Rng rng(3);
  for (int i = 0; i < 20; ++i) {
    const Quaterniond a = i == 0 ? Quaterniond::Identity() : random_quat(rng);
    const Quaterniond b = i == 1 ? exp_so3(Vector3d(M_PI, 0, 0)) : random_quat(rng);
    VectorXd x(8);
    x << quat_to_wxyz(a), quat_to_wxyz(b);
    Matrix3d Ja;
    Matrix3d Jb;
    compose(a, b, &Ja, &Jb);
    MatrixXd J(3, 6);
    J << Ja, Jb;
    const auto f = [](const VectorXd& x) {
      return VectorXd(quat_to_wxyz(compose(quat_from_wxyz(x.head<4>()), quat_from_wxyz(x.tail<4>()))));
    };
    EXPECT_TRUE(check_jacobian("compose", f, x, J, Layout::quaternion().then_quaternion(), Layout::quaternion()));

    Matrix3d Ji;
    inverse(a, &Ji);
    const auto g = [](const VectorXd& x) { return VectorXd(quat_to_wxyz(inverse(quat_from_wxyz(x.head<4>())))); };
    EXPECT_TRUE(check_jacobian("inverse", g, quat_to_wxyz(a), Ji, Layout::quaternion(), Layout::quaternion()));
  }
}

TEST(Rotation, NormalizeJacobianMatchesNumeric) {
  const Vector4d q(0.9, -0.3, 0.2, 0.4);
  Matrix4d J;
  normalize_quaternion(q, &J);
  const auto f = [](const VectorXd& x) { return VectorXd(normalize_quaternion(x.head<4>())); };
  EXPECT_TRUE(check_jacobian("normalize", f, q, J, Layout::euclidean(4), Layout::euclidean(4)));
  EXPECT_NEAR(normalize_quaternion(q).norm(), 1.0, 1e-15);
}

TEST(Rotation, ComposePosesJacobiansMatchNumeric) {
  Rng rng(5);
  for (int i = 0; i < 10; ++i) {
    const Pose A{random_quat(rng), randn_vec<3>(rng)};
    const Pose B{random_quat(rng), randn_vec<3>(rng)};
    Eigen::Matrix<double, 6, 6> JA;
    Eigen::Matrix<double, 6, 6> JB;
    compose_poses(A, B, &JA, &JB);
    const Layout pose = Layout::euclidean(3).then_quaternion();
    VectorXd x(14);
    x << A.p, quat_to_wxyz(A.q), B.p, quat_to_wxyz(B.q);
    const auto f = [](const VectorXd& x) {
      const Pose a{quat_from_wxyz(x.segment<4>(3)), x.head<3>()};
      const Pose b{quat_from_wxyz(x.segment<4>(10)), x.segment<3>(7)};
      const Pose c = compose_poses(a, b);
      VectorXd y(7);
      y << c.p, quat_to_wxyz(c.q);
      return y;
    };
    MatrixXd J(6, 12);
    J << JA, JB;
    EXPECT_TRUE(check_jacobian("compose_poses", f, x, J, Layout(pose).then_euclidean(3).then_quaternion(), pose));
    const Pose C = A * B;
    EXPECT_LT((C.transform(Vector3d(1, 2, 3)) - A.transform(B.transform(Vector3d(1, 2, 3)))).norm(), 1e-12);
    EXPECT_LT((A.inverse().transform(A.transform(Vector3d(1, 2, 3))) - Vector3d(1, 2, 3)).norm(), 1e-12);
  }
}

}  // namespace
}  // namespace rtslam::math
