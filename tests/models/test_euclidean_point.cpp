#include "rtslam/models/landmarks/euclidean_point.hpp"

#include <vector>

#include <gtest/gtest.h>

#include "models/pose_samples.hpp"
#include "rtslam/core/random.hpp"
#include "support/jacobian_check.hpp"

namespace rtslam::models {
namespace {

using Eigen::Matrix3d;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;
using test::check_jacobian;
using test::JacobianCheckOptions;
using test::Layout;
using test_samples::sample_poses;
using test_samples::sample_rays;

math::Pose pose_from(const VectorXd& x) { return {math::quat_from_wxyz(x.segment<4>(3)), x.head<3>()}; }

TEST(EuclideanPoint, ToSensorJacobiansMatchNumeric) {
  Rng rng(21);
  const Layout in = Layout::euclidean(3).then_quaternion().then_euclidean(3);  // p_WS, q_WS, p_W
  for (const math::Pose& T : sample_poses(22)) {
    std::vector<Vector3d> points = {T.p, T.p + Vector3d(0, 0, 1e-9), Vector3d(1e3, -2e3, 5.0)};
    for (int i = 0; i < 4; ++i) points.push_back(randn_vec<3>(rng, 5.0));
    for (const Vector3d& p : points) {
      Matrix3d Jp;
      Matrix3d Jq;
      Matrix3d Jl;
      const Vector3d h = point_to_sensor(p, T, &Jp, &Jq, &Jl);
      EXPECT_LT((T.transform(h) - p).norm(), 1e-12 * (1 + p.norm()));
      MatrixXd J(3, 9);
      J << Jp, Jq, Jl;
      VectorXd x(10);
      x << T.p, math::quat_to_wxyz(T.q), p;
      const auto f = [](const VectorXd& x) { return VectorXd(point_to_sensor(x.tail<3>(), pose_from(x))); };
      JacobianCheckOptions opt;
      opt.rtol = 1e-5;
      opt.atol = 1e-6 * (1 + (p - T.p).norm());
      EXPECT_TRUE(check_jacobian("point_to_sensor", f, x, J, in, Layout::euclidean(3), opt));
    }
  }
}

TEST(EuclideanPoint, FromRayJacobiansMatchNumericAndRoundTrip) {
  const Layout in = Layout::euclidean(3).then_quaternion().then_euclidean(4);  // p_WS, q_WS, ray, d
  for (const math::Pose& T : sample_poses(23)) {
    for (const Vector3d& ray : sample_rays(24)) {
      for (double d : {0.0, 0.5, 20.0}) {
        Matrix3d Jp;
        Matrix3d Jq;
        Matrix3d Jr;
        Vector3d Jd;
        const Vector3d p = point_from_ray(T, ray, d, &Jp, &Jq, &Jr, &Jd);
        // Seen from the same pose, the point is at distance d along the ray.
        EXPECT_LT((point_to_sensor(p, T) - d * ray.normalized()).norm(), 1e-12 * (1 + d));
        MatrixXd J(3, 10);
        J << Jp, Jq, Jr, Jd;
        VectorXd x(11);
        x << T.p, math::quat_to_wxyz(T.q), ray, d;
        const auto f = [](const VectorXd& x) { return VectorXd(point_from_ray(pose_from(x), x.segment<3>(7), x[10])); };
        JacobianCheckOptions opt;
        opt.step = 1e-6 * std::min(1.0, ray.norm());
        EXPECT_TRUE(check_jacobian("point_from_ray", f, x, J, in, Layout::euclidean(3), opt));
      }
    }
  }
}

}  // namespace
}  // namespace rtslam::models
