// The absolute sensor models (models/sensors/absolute.hpp): values and analytic Jacobians against central
// differences over identity, near-identity, random and rotation-by-π robot poses and lever arms.
#include <gtest/gtest.h>

#include "support/jacobian_check.hpp"
#include "models/pose_samples.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/models/sensors/absolute.hpp"

namespace rtslam::models {
namespace {

using test::Layout;
using Eigen::VectorXd;

const Layout kPose = Layout::euclidean(3).then_quaternion();

VectorXd pose_state(const math::Pose& T) {
  VectorXd x(7);
  x << T.p, math::quat_to_wxyz(T.q);
  return x;
}
math::Pose pose_of(const VectorXd& x) { return {math::quat_from_wxyz(x.segment<4>(3)), x.head<3>()}; }

std::vector<Eigen::Vector3d> lever_arms() {
  Rng rng(17);
  std::vector<Eigen::Vector3d> out = {Eigen::Vector3d::Zero(), Eigen::Vector3d(0.0, 0.0, 1e-9),
                                      Eigen::Vector3d(0.1, -0.3, 0.8)};
  for (int i = 0; i < 3; ++i) out.push_back(randn_vec<3>(rng, 1.0));
  return out;
}

TEST(AbsolutePosition, IsTheAntennaPositionInTheWorld) {
  const math::Pose T_WR{math::exp_so3(Eigen::Vector3d(0.0, 0.0, M_PI / 2)), Eigen::Vector3d(1.0, 2.0, 3.0)};
  // x of R points along y of W: an antenna 1 m ahead along x_R sits at +1 m in y_W.
  EXPECT_TRUE(absolute_position(T_WR, Eigen::Vector3d(1.0, 0.0, 0.0)).isApprox(Eigen::Vector3d(1.0, 3.0, 3.0), 1e-12));
}

TEST(AbsolutePosition, JacobianMatchesNumeric) {
  for (const math::Pose& T_WR : test_samples::sample_poses(3)) {
    for (const Eigen::Vector3d& l : lever_arms()) {
      Eigen::Matrix<double, 3, 6> J;
      absolute_position(T_WR, l, &J);
      const auto f = [&](const VectorXd& x) -> VectorXd { return absolute_position(pose_of(x), l); };
      EXPECT_TRUE(test::check_jacobian("J_z_TWR", f, pose_state(T_WR), J, kPose, Layout::euclidean(3)));
    }
  }
}

TEST(AbsolutePose, JacobianMatchesNumeric) {
  Rng rng(5);
  for (const math::Pose& T_WR : test_samples::sample_poses(4)) {
    for (const Eigen::Vector3d& l : lever_arms()) {
      const math::Pose T_RM{math::exp_so3(randn_vec<3>(rng, 1.0)), l};
      Eigen::Matrix<double, 6, 6> J;
      const math::Pose T_WM = absolute_pose(T_WR, T_RM, &J);
      EXPECT_TRUE(T_WM.p.isApprox(T_WR.transform(l), 1e-12) || T_WM.p.norm() < 1e-12);
      const auto f = [&](const VectorXd& x) -> VectorXd { return pose_state(absolute_pose(pose_of(x), T_RM)); };
      EXPECT_TRUE(test::check_jacobian("J_TWM_TWR", f, pose_state(T_WR), J, kPose, kPose));
    }
  }
}

TEST(AbsolutePose, InnovationIsZeroAtThePredictionAndItsJacobianMatchesNumeric) {
  Rng rng(9);
  for (const math::Pose& h : test_samples::sample_poses(6)) {
    EXPECT_LT(pose_innovation(h, h).norm(), 1e-12);
    // Residuals from none to large (2.5 rad: far from the small-angle regime, below π).
    for (const double size : {0.0, 1e-6, 0.1, 1.0, 2.5}) {
      const Eigen::Vector3d r = randn_vec<3>(rng, 1.0).normalized() * size;
      const math::Pose z{h.q * math::exp_so3(r), h.p + randn_vec<3>(rng, 0.5)};
      Eigen::Matrix<double, 6, 6> J;
      const Eigen::Matrix<double, 6, 1> y = pose_innovation(z, h, &J);
      EXPECT_TRUE(y.tail<3>().isApprox(r, 1e-9) || r.norm() < 1e-12);
      const auto f = [&](const VectorXd& x) -> VectorXd { return pose_innovation(z, pose_of(x)); };
      EXPECT_TRUE(test::check_jacobian("J_y_h", f, pose_state(h), J, kPose, Layout::euclidean(6)));
    }
  }
}

}  // namespace
}  // namespace rtslam::models
