// The points demo's scene (sim/point_scene.hpp): its measurements are the projections of its points at its true
// poses, with the configured noise, inside the image margin; a seed gives one sequence; frames go in order.
#include "rtslam/sim/point_scene.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "rtslam/core/error.hpp"
#include "rtslam/sim/simulation.hpp"

namespace rtslam::sim {
namespace {

PointSceneOptions short_scene(double sigma_px) {
  PointSceneOptions o;
  o.duration_s = 2.0;
  o.n_points = 300;
  o.sigma_px = sigma_px;
  return o;
}

TEST(PointScene, NoiselessMeasurementsAreTheTruthsProjections) {
  PointScene scene(short_scene(0.0));
  const Trajectory truth = scene.groundtruth();
  ASSERT_EQ(static_cast<int>(truth.poses.size()), scene.frame_count());
  EXPECT_EQ(scene.frame_count(), 61);  // 2 s at 30 Hz, both ends
  const models::PinholeCamera camera(to_intrinsics(scene.camera()));
  const math::Pose T_RS = math::Pose::from_isometry(scene.camera().T_RS);
  const math::Pose start = scene.start_pose();
  EXPECT_TRUE(start.p.isApprox(truth.poses.front().p_WR));
  std::vector<ScenePoint> z;
  int measured = 0;
  for (int k = 0; k < scene.frame_count(); ++k) {
    scene.measure(k, z);
    EXPECT_EQ(truth.poses[static_cast<size_t>(k)].t, scene.frame_time(k));
    const StampedPose& T_WR = truth.poses[static_cast<size_t>(k)];
    const math::Pose T_WS = math::Pose{T_WR.q_WR, T_WR.p_WR} * T_RS;
    EXPECT_GT(z.size(), 20u) << "frame " << k << ": the room's points are in view";
    for (const ScenePoint& m : z) {
      EXPECT_TRUE(camera.in_image(m.z, 8.0)) << "frame " << k << ", point " << m.id;
      ASSERT_GE(m.id, 0);
      ASSERT_LT(m.id, 300);
      ++measured;
      Eigen::Vector2d expected;
      ASSERT_TRUE(camera.project(T_WS.inverse_transform(scene.points()[static_cast<size_t>(m.id)]), expected));
      EXPECT_LT((m.z - expected).norm(), 1e-9) << "frame " << k << ", point " << m.id;
    }
  }
  EXPECT_GT(measured, 61 * 20);
}

TEST(PointScene, SeedGivesOneSequenceAndNoiseHasItsStd) {
  PointScene a(short_scene(1.0)), b(short_scene(1.0)), clean(short_scene(0.0));
  std::vector<ScenePoint> za, zb, zc;
  double sum2 = 0.0;
  int n = 0;
  for (int k = 0; k < a.frame_count(); ++k) {
    a.measure(k, za);
    b.measure(k, zb);
    clean.measure(k, zc);
    ASSERT_EQ(za.size(), zb.size());
    for (size_t i = 0; i < za.size(); ++i) {
      EXPECT_EQ(za[i].id, zb[i].id);
      EXPECT_EQ(za[i].z, zb[i].z);
    }
    // The noiseless scene measures the same points (up to the margin's edge): compare where both have the point.
    size_t j = 0;
    for (const ScenePoint& m : za) {
      while (j < zc.size() && zc[j].id < m.id) ++j;
      if (j < zc.size() && zc[j].id == m.id) {
        sum2 += (m.z - zc[j].z).squaredNorm();
        n += 2;
      }
    }
  }
  ASSERT_GT(n, 2000);
  EXPECT_NEAR(std::sqrt(sum2 / n), 1.0, 0.05) << "pixel noise std";
}

TEST(PointScene, FramesGoInOrderAndOptionsAreChecked) {
  PointScene scene(short_scene(1.0));
  std::vector<ScenePoint> z;
  scene.measure(0, z);
  EXPECT_THROW(scene.measure(0, z), std::logic_error);
  EXPECT_THROW(scene.measure(2, z), std::logic_error);
  PointSceneOptions bad = short_scene(1.0);
  bad.rate_hz = 0.0;
  EXPECT_THROW(PointScene{bad}, ConfigError);
  bad = short_scene(1.0);
  bad.room_max = bad.room_min;
  EXPECT_THROW(PointScene{bad}, ConfigError);
}

}  // namespace
}  // namespace rtslam::sim
