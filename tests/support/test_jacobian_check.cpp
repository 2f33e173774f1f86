#include "support/jacobian_check.hpp"

namespace rtslam::test {
namespace {

TEST(JacobianCheck, AcceptsCorrectEuclideanJacobian) {
  const auto f = [](const VectorXd& x) {
    VectorXd y(2);
    y << x[0] * x[1], std::sin(x[0]);
    return y;
  };
  VectorXd x0(2);
  x0 << 0.3, -1.2;
  MatrixXd J(2, 2);
  J << x0[1], x0[0], std::cos(x0[0]), 0.0;
  EXPECT_TRUE(check_jacobian("f", f, x0, J, Layout::euclidean(2), Layout::euclidean(2)));
}

TEST(JacobianCheck, FailsOnWrongEntryAndPrintsBothMatrices) {
  const auto f = [](const VectorXd& x) { return VectorXd(x * 2.0); };
  const VectorXd x0 = VectorXd::Ones(3);
  MatrixXd J = 2.0 * MatrixXd::Identity(3, 3);
  J(1, 2) = 1e-3;  // a small but real error must be caught
  const auto r = check_jacobian("g", f, x0, J, Layout::euclidean(3), Layout::euclidean(3));
  EXPECT_FALSE(r);
  const std::string msg = r.message();
  EXPECT_NE(msg.find("analytic"), std::string::npos);
  EXPECT_NE(msg.find("numeric"), std::string::npos);
  EXPECT_NE(msg.find("(1,2)"), std::string::npos);
}

TEST(JacobianCheck, FailsOnSizeMismatch) {
  const auto f = [](const VectorXd& x) { return x; };
  EXPECT_FALSE(check_jacobian("h", f, VectorXd::Ones(3), MatrixXd::Identity(2, 2), Layout::euclidean(3),
                              Layout::euclidean(3)));
}

TEST(JacobianCheck, QuaternionLayoutRoundTrips) {
  const Layout l = Layout::euclidean(2).then_quaternion();
  VectorXd x(6);
  x << 1.0, 2.0, std::cos(0.4), std::sin(0.4), 0.0, 0.0;
  VectorXd dx(5);
  dx << 0.1, -0.2, 0.01, 0.02, -0.03;
  const VectorXd y = l.plus(x, dx);
  EXPECT_LT((l.minus(y, x) - dx).norm(), 1e-12);
}

}  // namespace
}  // namespace rtslam::test
