#pragma once
// The shared Jacobian checker for tests: central differences on manifold inputs, compared to an analytic
// Jacobian entry by entry with a relative tolerance and an absolute fallback. It FAILS (AssertionResult) and prints
// both matrices and the worst entry; use as EXPECT_TRUE(check_jacobian(...)).
//
// Inputs and outputs are described by a Layout: a sequence of Euclidean segments and unit-quaternion segments
// (ambient [qw qx qy qz], tangent δθ with the right perturbation q ⊕ δθ = q ⊗ Exp(δθ), as the filter uses).
// The Jacobian maps input tangent perturbations to output tangent perturbations.
#include <cmath>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "rtslam/math/rotation.hpp"

namespace rtslam::test {

using Eigen::MatrixXd;
using Eigen::VectorXd;

/// Segments of a (possibly manifold) vector: Euclidean(n) or Quaternion (4 ambient, 3 tangent).
class Layout {
 public:
  static Layout euclidean(int n) { return Layout().then_euclidean(n); }
  static Layout quaternion() { return Layout().then_quaternion(); }
  Layout& then_euclidean(int n) {
    segments_.push_back(n);
    return *this;
  }
  Layout& then_quaternion() {
    segments_.push_back(-1);
    return *this;
  }
  int ambient_size() const {
    int s = 0;
    for (int n : segments_) s += n < 0 ? 4 : n;
    return s;
  }
  int tangent_size() const {
    int s = 0;
    for (int n : segments_) s += n < 0 ? 3 : n;
    return s;
  }
  /// x ⊕ dx.
  VectorXd plus(const VectorXd& x, const VectorXd& dx) const {
    VectorXd out = x;
    int a = 0;
    int t = 0;
    for (int n : segments_) {
      if (n < 0) {
        const auto q = math::quat_from_wxyz(x.segment<4>(a));
        out.segment<4>(a) = math::quat_to_wxyz(math::boxplus(q, dx.segment<3>(t)));
        a += 4;
        t += 3;
      } else {
        out.segment(a, n) += dx.segment(t, n);
        a += n;
        t += n;
      }
    }
    return out;
  }
  /// y1 ⊖ y0 (for a quaternion: Log(q0⁻¹ ⊗ q1)).
  VectorXd minus(const VectorXd& y1, const VectorXd& y0) const {
    VectorXd out(tangent_size());
    int a = 0;
    int t = 0;
    for (int n : segments_) {
      if (n < 0) {
        out.segment<3>(t) =
            math::boxminus(math::quat_from_wxyz(y1.segment<4>(a)), math::quat_from_wxyz(y0.segment<4>(a)));
        a += 4;
        t += 3;
      } else {
        out.segment(t, n) = y1.segment(a, n) - y0.segment(a, n);
        a += n;
        t += n;
      }
    }
    return out;
  }

 private:
  std::vector<int> segments_;
};

struct JacobianCheckOptions {
  double step = 1e-6;   // central-difference step on the input tangent space
  double rtol = 1e-5;   // relative tolerance on |analytic − numeric| / |numeric|
  double atol = 1e-6;   // absolute fallback, for entries near zero
};

/// Numerical Jacobian of f at x0 by central differences on the tangent spaces.
inline MatrixXd numeric_jacobian(const std::function<VectorXd(const VectorXd&)>& f, const VectorXd& x0,
                                 const Layout& in, const Layout& out, double step) {
  const VectorXd y0 = f(x0);
  MatrixXd J(out.tangent_size(), in.tangent_size());
  for (int j = 0; j < in.tangent_size(); ++j) {
    VectorXd dx = VectorXd::Zero(in.tangent_size());
    dx[j] = step;
    const VectorXd yp = f(in.plus(x0, dx));
    const VectorXd ym = f(in.plus(x0, -dx));
    J.col(j) = (out.minus(yp, y0) - out.minus(ym, y0)) / (2.0 * step);
  }
  return J;
}

/// Checks an analytic Jacobian against central differences. `what` names the Jacobian in the failure message.
inline ::testing::AssertionResult check_jacobian(const std::string& what,
                                                 const std::function<VectorXd(const VectorXd&)>& f,
                                                 const VectorXd& x0, const MatrixXd& J_analytic, const Layout& in,
                                                 const Layout& out, JacobianCheckOptions opt = {}) {
  if (x0.size() != in.ambient_size() || J_analytic.cols() != in.tangent_size() ||
      J_analytic.rows() != out.tangent_size()) {
    return ::testing::AssertionFailure() << what << ": size mismatch: x0 " << x0.size() << ", J "
                                         << J_analytic.rows() << "x" << J_analytic.cols() << ", layouts in "
                                         << in.ambient_size() << "/" << in.tangent_size() << " out "
                                         << out.tangent_size();
  }
  const MatrixXd J_num = numeric_jacobian(f, x0, in, out, opt.step);
  double worst = 0.0;
  int wi = -1;
  int wj = -1;
  bool ok = J_num.allFinite() && J_analytic.allFinite();
  for (int i = 0; i < J_num.rows(); ++i) {
    for (int j = 0; j < J_num.cols(); ++j) {
      const double diff = std::abs(J_analytic(i, j) - J_num(i, j));
      const double tol = std::max(opt.atol, opt.rtol * std::abs(J_num(i, j)));
      if (!(diff <= tol)) {
        ok = false;
        if (diff / tol > worst || wi < 0) {
          worst = diff / tol;
          wi = i;
          wj = j;
        }
      }
    }
  }
  if (ok) return ::testing::AssertionSuccess();
  std::ostringstream s;
  const Eigen::IOFormat fmt(8, 0, ", ", "\n", "  [", "]");
  s << what << ": analytic and numeric Jacobians differ";
  if (wi >= 0) s << " (worst entry (" << wi << "," << wj << "): " << worst << "x tolerance)";
  s << "\nanalytic:\n" << J_analytic.format(fmt) << "\nnumeric:\n" << J_num.format(fmt) << "\nat x0 = "
    << x0.transpose();
  return ::testing::AssertionFailure() << s.str();
}

}  // namespace rtslam::test
