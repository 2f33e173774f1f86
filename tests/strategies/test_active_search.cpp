// The image data manager on synthetic images: a textured plane (random overlapping rectangles, seeded) rendered by
// ray casting through an undistorted pinhole camera. Checks matching of the predicted appearance, one-point RANSAC
// rejecting a planted outlier (a landmark whose texture was moved inside its search ellipse), and tracking over a
// short sequence through the System.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <utility>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/slam/landmark_init.hpp"
#include "rtslam/slam/system.hpp"
#include "rtslam/strategies/active_search.hpp"
#include "rtslam/strategies/init_grid.hpp"
#include "rtslam/strategies/map_policies.hpp"
#include "rtslam/vision/warp.hpp"
#include "rtslam/vision/zncc.hpp"
#include "support/test_camera.hpp"

namespace rtslam::strategies {
namespace {

constexpr double kPlaneZ = 2.0;       // the textured plane Z = 2 m in W
constexpr double kTexelM = 0.004;     // texture resolution (m per texel)
constexpr int kTexSize = 1200;        // texels: the plane spans [-2.4, 2.4] m

vision::Image make_texture(std::uint64_t seed) {
  Rng rng(seed);
  vision::Image tex(kTexSize, kTexSize, 128);
  for (int k = 0; k < 2500; ++k) {
    const int w = static_cast<int>(randu(rng, 6, 40)), h = static_cast<int>(randu(rng, 6, 40));
    const int x = static_cast<int>(randu(rng, 0, kTexSize - w)), y = static_cast<int>(randu(rng, 0, kTexSize - h));
    const auto g = static_cast<std::uint8_t>(randu(rng, 15, 240));
    for (int v = y; v < y + h; ++v)
      for (int u = x; u < x + w; ++u) tex.at(u, v) = g;
  }
  return tex;
}

models::CameraIntrinsics test_camera() {
  return support::qvga_camera();
}

/// Renders the plane seen from camera pose T_WC (optical frame), bilinear texture lookup.
vision::Image render(const vision::Image& tex, const math::Pose& T_WC) {
  const models::CameraIntrinsics c = test_camera();
  vision::Image img(c.width, c.height, 0);
  const Eigen::Matrix3d R = T_WC.q.toRotationMatrix();
  for (int v = 0; v < c.height; ++v) {
    for (int u = 0; u < c.width; ++u) {
      const Eigen::Vector3d d = R * Eigen::Vector3d((u - c.cx) / c.fx, (v - c.cy) / c.fy, 1.0);
      const double t = (kPlaneZ - T_WC.p.z()) / d.z();
      const Eigen::Vector3d p = T_WC.p + t * d;
      const double tu = p.x() / kTexelM + 0.5 * kTexSize, tv = p.y() / kTexelM + 0.5 * kTexSize;
      img.at(u, v) = static_cast<std::uint8_t>(vision::sample_bilinear(tex.view(), tu, tv) + 0.5);
    }
  }
  return img;
}

math::Pose pose_of(const Eigen::Vector3d& p, const Eigen::Vector3d& rotvec) {
  math::Pose T;
  T.p = p;
  const double a = rotvec.norm();
  T.q = a > 0 ? Eigen::Quaterniond(Eigen::AngleAxisd(a, rotvec / a)) : Eigen::Quaterniond::Identity();
  return T;
}

Eigen::Vector2d project_true(const math::Pose& T_WC, const Eigen::Vector3d& p_W) {
  const models::CameraIntrinsics c = test_camera();
  const Eigen::Vector3d p = T_WC.inverse_transform(p_W);
  return {c.fx * p.x() / p.z() + c.cx, c.fy * p.y() / p.z() + c.cy};
}

/// A map with one constant-velocity robot carrying the test camera (T_RS = identity), at pose T_WR0, with zero
/// covariance (the gauge).
struct Rig {
  slam::World world;
  slam::Map* map = nullptr;
  slam::Sensor* sensor = nullptr;
  slam::Robot* robot = nullptr;
  PolicyMapManager map_manager{MapPolicyOptions{}};

  explicit Rig(const math::Pose& T_WR0) {
    map = &world.add_map();
    auto r = std::make_unique<slam::ConstantVelocityRobot>(models::ConstantVelocityParams{});
    sensor = &r->add_sensor(std::make_unique<slam::PinholeSensor>("cam", test_camera(), math::Pose::identity()));
    Eigen::VectorXd x0 = Eigen::VectorXd::Zero(13);
    x0.head<3>() = T_WR0.p;
    x0.segment<4>(3) = math::quat_to_wxyz(T_WR0.q);
    Eigen::MatrixXd P0 = Eigen::MatrixXd::Zero(12, 12);
    P0.bottomRightCorner<6, 6>() = 0.25 * Eigen::MatrixXd::Identity(6, 6);
    robot = &map->add_robot(std::move(r), x0, P0, 0);
  }
};

/// One frame of `img` through the data manager; returns its statistics.
slam::FrameStats process_frame(Rig& rig, ActiveSearchDataManager& dm, const vision::Image& img, long frame) {
  RawImage raw;
  raw.image = img.view();
  slam::FrameStats stats;
  dm.process(*rig.map, *rig.sensor, raw, frame, stats);
  return stats;
}

/// Frame 0 (initialization by the data manager), then the landmarks' depths are set to the truth with a small
/// uncertainty and the robot gets a pose prior of std (sigma_p, sigma_th) around the frame-0 pose: the situation of
/// a tracked map after a prediction. Returns the true 3D points of the landmarks, by landmark id.
std::vector<Eigen::Vector3d> init_known_depth_map(Rig& rig, ActiveSearchDataManager& dm, const vision::Image& img0,
                                                  double sigma_p, double sigma_th) {
  EXPECT_GE(process_frame(rig, dm, img0, 0).initialized, 12);
  filter::State& state = rig.map->state();
  std::vector<Eigen::Vector3d> truth(rig.map->landmarks().size());
  for (const auto& l : rig.map->landmarks()) {
    auto L = state.mean(l->block());
    const Eigen::Vector3d p0 = L.head<3>(), m = L.segment<3>(3);
    const double t = (kPlaneZ - p0.z()) / m.z();  // p = p0 + t m on the plane: ρ = 1/t
    L[6] = 1.0 / t;
    Eigen::Matrix<double, 7, 1> var;
    var << 1e-10, 1e-10, 1e-10, 1e-8, 1e-8, 1e-8, std::pow(0.002 / t, 2);
    state.cov(l->block(), l->block()) = var.asDiagonal().toDenseMatrix();
    truth[static_cast<size_t>(l->id())] = p0 + t * m;
  }
  Eigen::Matrix<double, 6, 1> pv;
  pv << Eigen::Vector3d::Constant(sigma_p * sigma_p), Eigen::Vector3d::Constant(sigma_th * sigma_th);
  state.cov(rig.robot->block(), rig.robot->block()).topLeftCorner<6, 6>() = pv.asDiagonal().toDenseMatrix();
  return truth;
}

/// Moves the texture around the true pixel of landmark `victim` by `offset` px and flattens its old place.
void plant_outlier(vision::Image& img, const Eigen::Vector2d& z, int offset) {
  const int cu = static_cast<int>(std::lround(z.x())), cv = static_cast<int>(std::lround(z.y()));
  constexpr int kHalf = 10;
  vision::Image copy = vision::Image::copy_of(img.roi(cu - kHalf, cv - kHalf, 2 * kHalf + 1, 2 * kHalf + 1));
  for (int v = -kHalf - 2; v <= kHalf + 2; ++v)
    for (int u = -kHalf - 2; u <= kHalf + 2; ++u) img.at(cu + u, cv + v) = 128;
  for (int v = -kHalf; v <= kHalf; ++v)
    for (int u = -kHalf; u <= kHalf; ++u) img.at(cu + offset + u, cv + v) = copy.at(u + kHalf, v + kHalf);
}

struct OutlierScene {
  vision::Image tex = make_texture(7);
  math::Pose T0 = math::Pose::identity();
  math::Pose T1 = pose_of({0.03, -0.02, 0.01}, {0.004, -0.006, 0.003});
  vision::Image img0 = render(tex, T0);
  vision::Image img1 = render(tex, T1);
};

/// The first landmark whose planted copy (offset px to the right) stays clear of every other landmark.
int choose_victim(const std::vector<Eigen::Vector3d>& truth, const math::Pose& T1, int offset) {
  for (size_t i = 0; i < truth.size(); ++i) {
    const Eigen::Vector2d zi = project_true(T1, truth[i]);
    if (zi.x() < 30 || zi.x() > 320 - 30 - offset || zi.y() < 30 || zi.y() > 210) continue;
    bool clear = true;
    for (size_t j = 0; j < truth.size(); ++j) {
      if (j == i) continue;
      const Eigen::Vector2d zj = project_true(T1, truth[j]);
      if (std::abs(zj.y() - zi.y()) < 26 && zj.x() > zi.x() - 26 && zj.x() < zi.x() + offset + 26) clear = false;
    }
    if (clear) return static_cast<int>(i);
  }
  return -1;
}

/// The corrected pose is close to the truth (the prior was 3.7 cm and 0.44° off, with std 3 cm and 0.57°) and
/// consistent with the filter's covariance: NEES of [δp δθ] below χ²₆(0.999) = 22.46.
void expect_pose_consistent(const Rig& rig, const math::Pose& T_true) {
  const math::Pose est = rig.robot->pose();
  Eigen::Matrix<double, 6, 1> e;
  e.head<3>() = T_true.p - est.p;
  const Eigen::AngleAxisd aa(est.q.conjugate() * T_true.q);
  e.tail<3>() = aa.angle() * aa.axis();
  const Eigen::Matrix<double, 6, 6> P = rig.map->state().cov(rig.robot->block()).topLeftCorner<6, 6>();
  const double nees = e.dot(P.ldlt().solve(e));
  EXPECT_LT(e.head<3>().norm(), 0.012);
  EXPECT_LT(e.tail<3>().norm(), 0.006);
  EXPECT_LT(nees, 22.46) << "error " << e.transpose();
}

ActiveSearchOptions test_options() {
  ActiveSearchOptions o;
  o.max_inits = 24;
  return o;
}

TEST(ActiveSearch, MatchesPredictedAppearanceAndCorrectsPose) {
  OutlierScene s;
  Rig rig(s.T0);
  ActiveSearchDataManager dm(test_options(), rig.map_manager, 320, 240, 11);
  const auto truth = init_known_depth_map(rig, dm, s.img0, 0.03, 0.01);
  const slam::FrameStats stats = process_frame(rig, dm, s.img1, 1);
  EXPECT_GE(stats.updated, 10);
  EXPECT_GE(stats.ransac_inliers, 5);
  int checked = 0;
  for (const auto& m : dm.last_frame()) {
    if (!m.matched) continue;
    EXPECT_LT((m.z - project_true(s.T1, truth[static_cast<size_t>(m.landmark_id)])).norm(), 0.6)
        << "landmark " << m.landmark_id;
    ++checked;
  }
  EXPECT_GE(checked, 10);
  expect_pose_consistent(rig, s.T1);
}

// An uncertain pose (std 15 cm at 2 m: 3σ boxes of about 110 x 110 px, above max_search_size_px2) leaves no box
// small enough. RT-SLAM's rule alone (min_candidates 0) searches nothing, so the uncertainty can only grow; with
// the fallback the min_candidates smallest boxes are searched, matched at the true pixels and corrected.
TEST(ActiveSearch, WhenEveryBoxIsTooLargeTheSmallestAreSearchedAnyway) {
  for (const int min_candidates : {0, 4}) {
    SCOPED_TRACE(min_candidates);
    OutlierScene s;
    Rig rig(s.T0);
    ActiveSearchOptions o = test_options();
    o.min_candidates = min_candidates;
    ActiveSearchDataManager dm(o, rig.map_manager, 320, 240, 11);
    const auto truth = init_known_depth_map(rig, dm, s.img0, 0.15, 0.01);
    const slam::FrameStats stats = process_frame(rig, dm, s.img1, 1);
    int oversized = 0;
    for (const auto& m : dm.last_frame()) {
      const vision::Roi box = vision::SearchEllipse::from_covariance(m.h, m.S, o.n_sigma).bounding_box();
      if (static_cast<double>(box.w) * box.h > o.max_search_size_px2) ++oversized;
    }
    if (min_candidates == 0) {
      EXPECT_EQ(stats.fallback, 0);
      EXPECT_EQ(stats.visible, 0);
      EXPECT_EQ(stats.searched, 0);
      EXPECT_EQ(stats.updated, 0);
      continue;
    }
    EXPECT_EQ(stats.visible, 4);
    EXPECT_EQ(stats.fallback, 4);
    EXPECT_EQ(stats.searched, 4);
    EXPECT_EQ(oversized, 4);  // every candidate of the frame came through the fallback
    EXPECT_GE(stats.updated, 3);
    for (const auto& m : dm.last_frame()) {
      if (!m.updated) continue;
      EXPECT_LT((m.z - project_true(s.T1, truth[static_cast<size_t>(m.landmark_id)])).norm(), 0.6)
          << "landmark " << m.landmark_id;
    }
    const Eigen::Matrix3d P = rig.map->state().cov(rig.robot->block()).topLeftCorner<3, 3>();
    EXPECT_LT(std::sqrt(P.trace() / 3.0), 0.15 / 2);  // the uncertainty shrank
    EXPECT_LT((rig.robot->pose().p - s.T1.p).norm(), (s.T0.p - s.T1.p).norm());
  }
}

TEST(ActiveSearch, RansacStopsOnceAnInlierWasDrawnWithTheConfidence) {
  // Stops when (1 − ε)^k ≤ 1 − confidence after k hypotheses, ε = best support / candidates.
  EXPECT_FALSE(ransac_may_stop(1, 24, 25, 0.99));  // ε 0.96: 0.04 > 0.01
  EXPECT_TRUE(ransac_may_stop(2, 24, 25, 0.99));   // 0.0016
  EXPECT_FALSE(ransac_may_stop(6, 10, 20, 0.99));  // ε 0.5: 0.0156
  EXPECT_TRUE(ransac_may_stop(7, 10, 20, 0.99));   // 0.0078
  EXPECT_FALSE(ransac_may_stop(2, 9, 10, 0.999));  // ε 0.9: 0.01 > 0.001
  EXPECT_TRUE(ransac_may_stop(3, 9, 10, 0.999));
  EXPECT_TRUE(ransac_may_stop(1, 20, 20, 0.99));   // every candidate supports the first hypothesis
  EXPECT_FALSE(ransac_may_stop(1000, 20, 20, 0.0));  // off
  EXPECT_FALSE(ransac_may_stop(1000, 1, 1, 0.99));   // no support set to correct with
  EXPECT_FALSE(ransac_may_stop(1000, 5, 0, 0.99));
  EXPECT_FALSE(ransac_may_stop(0, 20, 20, 0.99));
}

TEST(ActiveSearch, RansacDrawsFewerHypothesesWhenTheSupportIsLarge) {
  // No outlier: the first matched hypothesis is supported by nearly every candidate, so the adaptive count stops
  // after one or two; with the confidence off, every one of the ransac_ntries draws is a hypothesis. Both correct
  // the pose as well.
  for (const double confidence : {0.99, 0.0}) {
    SCOPED_TRACE(confidence);
    OutlierScene s;
    Rig rig(s.T0);
    ActiveSearchOptions o = test_options();
    o.ransac_confidence = confidence;
    ActiveSearchDataManager dm(o, rig.map_manager, 320, 240, 11);
    init_known_depth_map(rig, dm, s.img0, 0.03, 0.01);
    const slam::FrameStats stats = process_frame(rig, dm, s.img1, 1);
    ASSERT_GE(stats.visible, 10);
    if (confidence > 0.0) {
      EXPECT_GE(stats.ransac_hypotheses, 1);
      EXPECT_LE(stats.ransac_hypotheses, 2);
    } else {
      EXPECT_EQ(stats.ransac_hypotheses, o.ransac_ntries);
    }
    EXPECT_GE(stats.ransac_inliers, 5);
    EXPECT_GE(stats.updated, 10);
    expect_pose_consistent(rig, s.T1);
  }
}

TEST(ActiveSearch, OnePointRansacRejectsPlantedOutlier) {
  OutlierScene s;
  Rig rig(s.T0);
  ActiveSearchDataManager dm(test_options(), rig.map_manager, 320, 240, 11);
  const auto truth = init_known_depth_map(rig, dm, s.img0, 0.03, 0.01);
  constexpr int kOffset = 12;
  const int victim = choose_victim(truth, s.T1, kOffset);
  ASSERT_GE(victim, 0);
  const Eigen::Vector2d z_true = project_true(s.T1, truth[static_cast<size_t>(victim)]);
  vision::Image img1 = s.img1;
  plant_outlier(img1, z_true, kOffset);
  const slam::FrameStats stats = process_frame(rig, dm, img1, 1);
  bool seen = false;
  for (const auto& m : dm.last_frame()) {
    if (m.landmark_id != victim) continue;
    seen = true;
    // The planted copy lies inside the first (prior) ellipse.
    const Eigen::Vector2d e = z_true + Eigen::Vector2d(kOffset, 0) - m.h;
    EXPECT_LT(e.dot(m.S.inverse() * e), 9.0);
    EXPECT_FALSE(m.ransac_inlier);
    EXPECT_FALSE(m.updated);
  }
  EXPECT_TRUE(seen);
  EXPECT_GE(stats.updated, 10);
  expect_pose_consistent(rig, s.T1);
}

TEST(ActiveSearch, WithoutRansacThePlantedOutlierIsMatched) {
  // Control for the test above: the planted copy is what ZNCC finds in the full ellipse.
  OutlierScene s;
  Rig rig(s.T0);
  ActiveSearchOptions o = test_options();
  o.ransac_ntries = 0;
  o.gain_recomputations = 1;  // everything searched in the prior ellipses
  ActiveSearchDataManager dm(o, rig.map_manager, 320, 240, 11);
  const auto truth = init_known_depth_map(rig, dm, s.img0, 0.03, 0.01);
  constexpr int kOffset = 12;
  const int victim = choose_victim(truth, s.T1, kOffset);
  ASSERT_GE(victim, 0);
  const Eigen::Vector2d z_true = project_true(s.T1, truth[static_cast<size_t>(victim)]);
  vision::Image img1 = s.img1;
  plant_outlier(img1, z_true, kOffset);
  const slam::FrameStats stats = process_frame(rig, dm, img1, 1);
  EXPECT_EQ(stats.ransac_inliers, 0);
  bool matched_wrong = false;
  for (const auto& m : dm.last_frame()) {
    if (m.landmark_id == victim && m.matched) matched_wrong = (m.z - z_true).norm() > kOffset - 1.0;
  }
  EXPECT_TRUE(matched_wrong);
}

TEST(ActiveSearch, InitializesLandmarksWithPatchAndView) {
  OutlierScene s;
  Rig rig(s.T0);
  ActiveSearchDataManager dm(test_options(), rig.map_manager, 320, 240, 3);
  const slam::FrameStats stats = process_frame(rig, dm, s.img0, 0);
  ASSERT_GE(stats.initialized, 12);
  EXPECT_LE(stats.initialized, 24);
  for (const auto& l : rig.map->landmarks()) {
    EXPECT_EQ(l->type(), slam::LandmarkType::AhpPoint);
    const PointDescriptor* d = point_descriptor(*l);
    ASSERT_NE(d, nullptr);
    EXPECT_EQ(d->patch.width(), 31);
    // The stored patch is the image around the corner.
    const int u0 = static_cast<int>(d->patch_centre_px.x()) - 15, v0 = static_cast<int>(d->patch_centre_px.y()) - 15;
    EXPECT_EQ(d->patch.at(7, 9), s.img0.at(u0 + 7, v0 + 9));
    // The sub-pixel corner lies near the response maximum the patch is centred on.
    EXPECT_LT((d->z0_px - d->patch_centre_px).norm(), 4.0);
    EXPECT_LT((d->T_WS0.p - s.T0.p).norm(), 1e-12);
  }
  // Two landmarks per grid cell at most are impossible: they are at least a few pixels apart.
  for (size_t i = 0; i < rig.map->landmarks().size(); ++i)
    for (size_t j = i + 1; j < rig.map->landmarks().size(); ++j)
      EXPECT_GT((point_descriptor(*rig.map->landmarks()[i])->z0_px - point_descriptor(*rig.map->landmarks()[j])->z0_px)
                    .norm(),
                3.0);
}

struct TrackResult {
  std::vector<math::Pose> est;
  std::vector<slam::FrameStats> stats;
};

TrackResult track_sequence(std::uint64_t seed, int n_frames) {
  const vision::Image tex = make_texture(5);
  TrackResult r;
  Rig rig(math::Pose::identity());
  slam::System system(*rig.map, std::make_unique<PolicyMapManager>(MapPolicyOptions{}));
  ActiveSearchOptions o;
  o.prior.d_min = 1.0;
  rig.sensor->set_data_manager(std::make_unique<ActiveSearchDataManager>(o, rig.map_manager, 320, 240, seed));
  for (int k = 0; k < n_frames; ++k) {
    const double t = k / 30.0;
    const math::Pose T = pose_of({0.25 * t, 0.1 * std::sin(3.0 * t), 0.0}, {0.0, 0.05 * std::sin(2.0 * t), 0.0});
    const vision::Image img = render(tex, T);
    RawImage raw;
    raw.t = from_seconds(t);
    raw.sensor_id = rig.sensor->id();
    raw.image = img.view();
    r.stats.push_back(system.process(raw));
    r.est.push_back(rig.robot->pose());
  }
  return r;
}

TEST(ActiveSearch, TracksAMovingCameraDeterministically) {
  constexpr int kFrames = 45;
  // Rotation is observable at once; translation up to the (weakly known) monocular scale: check its direction.
  // The final attitude error varies with the seed's draws (RANSAC, grid) by a few mrad, and one seed in six or
  // seven ends beyond 10 mrad (30 seeds, with 6 hypotheses a frame or the adaptive count alike): five seeds, their
  // median within 10 mrad and none beyond 30.
  const double t_end = (kFrames - 1) / 30.0;
  const math::Pose T_end =
      pose_of({0.25 * t_end, 0.1 * std::sin(3.0 * t_end), 0.0}, {0.0, 0.05 * std::sin(2.0 * t_end), 0.0});
  std::vector<double> attitude_errors;
  TrackResult a;  // seed 21's, run again below for determinism
  for (std::uint64_t seed = 21; seed <= 25; ++seed) {
    TrackResult r = track_sequence(seed, kFrames);
    for (int k = 5; k < kFrames; ++k) {
      EXPECT_GE(r.stats[static_cast<size_t>(k)].updated, 8) << "seed " << seed << ", frame " << k;
    }
    attitude_errors.push_back(r.est.back().q.angularDistance(T_end.q));
    EXPECT_LT(attitude_errors.back(), 0.03) << "seed " << seed;
    EXPECT_GT(r.est.back().p.normalized().dot(T_end.p.normalized()), 0.95) << "seed " << seed;
    if (seed == 21) a = std::move(r);
  }
  std::nth_element(attitude_errors.begin(), attitude_errors.begin() + 2, attitude_errors.end());
  EXPECT_LT(attitude_errors[2], 0.01);
  const TrackResult b = track_sequence(21, kFrames);
  for (int k = 0; k < kFrames; ++k) {
    EXPECT_EQ(a.est[static_cast<size_t>(k)].p, b.est[static_cast<size_t>(k)].p);
    EXPECT_EQ(a.est[static_cast<size_t>(k)].q.coeffs(), b.est[static_cast<size_t>(k)].q.coeffs());
  }
}

TEST(ActiveSearchOptions, RejectsBadValuesNamingTheKey) {
  ActiveSearchOptions o;
  o.max_updates_ransac = 40;
  try {
    o.validate();
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("max_updates_ransac"), std::string::npos);
  }
  YAML::Node n = YAML::Load("{sigma_px: 1.5, grid: {cells_x: 8}, zncc: {threshold: 0.85}, bogus: 1}");
  YamlMap m(n, "test.yaml");
  EXPECT_THROW(ActiveSearchOptions::from_yaml(m), ConfigError);
  YAML::Node good = YAML::Load("{sigma_px: 1.5, grid: {cells_x: 8}, zncc: {threshold: 0.85}}");
  YamlMap g(good, "test.yaml");
  const ActiveSearchOptions p = ActiveSearchOptions::from_yaml(g);
  EXPECT_EQ(p.sigma_px, 1.5);
  EXPECT_EQ(p.grid.cells_x, 8);
  EXPECT_EQ(p.zncc.threshold, 0.85);
}

}  // namespace
}  // namespace rtslam::strategies

namespace rtslam::strategies {
namespace {

std::string config_error_of(const std::string& yaml) {
  try {
    YamlMap top(YAML::Load(yaml), "cfg.yaml");
    YamlMap s = top.child("search");
    ActiveSearchOptions::from_yaml(s);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}

// Issue 17: search, zncc, grid and d_min errors named neither the file nor the key path; a 100000x100000 grid hung.
TEST(ActiveSearchOptionsBounds, ErrorsNameTheFileTheKeyPathAndTheBound) {
  EXPECT_EQ(config_error_of("search: {grid: {cells_x: 100000, cells_y: 100000}}"),
            "cfg.yaml/search/grid: cells_x = 100000 must be in [1, 64]");
  EXPECT_EQ(config_error_of("search: {zncc: {threshold: 2}}"), "cfg.yaml/search/zncc: threshold = 2 must be in [-1, 1]");
  EXPECT_EQ(config_error_of("search: {d_min: -1}"), "cfg.yaml/search: d_min = -1 must be in [1e-3, 1e4] m");
  EXPECT_EQ(config_error_of("search: {n_sigma: 1e9}"), "cfg.yaml/search: n_sigma = 1000000000 must be in (0, 10]");
  EXPECT_EQ(config_error_of("search: {harris: {border_px: 100000}}"),
            "cfg.yaml/search/harris: border_px = 100000 must be in [0, 1000] px");
  EXPECT_EQ(config_error_of("search: {min_candidates: -1}"),
            "cfg.yaml/search: min_candidates = -1 must be in [0, 1000]");
  EXPECT_EQ(config_error_of("search: {n_sigma: 3}"), "(no error)");
}

TEST(ActiveSearchOptionsBounds, GridCellsSmallerThanFourPixelsOnTheImageAreRefused) {
  InitGridOptions g;
  g.cells_x = 64;
  g.cells_y = 4;
  EXPECT_THROW(InitGrid(200, 100, g), ConfigError);  // (200 - 16) / 64 = 2.9 px
  EXPECT_NO_THROW(InitGrid(752, 480, g));
}

TEST(MapPolicyOptionsBounds, MapSizeHasAnUpperBound) {
  MapPolicyOptions m;
  m.map_size = 1'000'000;
  EXPECT_THROW(m.validate(), ConfigError);
  m.map_size = 500;
  EXPECT_NO_THROW(m.validate());
}

/// A budget clock that advances by `step_ms` at each reading: the data manager reads it once when the search starts,
/// once before each ZNCC search it may start (until the budget is spent) and once at the end.
class SteppingClock final : public BudgetClock {
 public:
  explicit SteppingClock(double step_ms) : step_ms_(step_ms) {}
  double now_ms() override { return step_ms_ * static_cast<double>(reads_++); }
  int reads() const { return reads_; }

 private:
  double step_ms_;
  int reads_ = 0;
};

/// Frame 1 of the outlier scene (no outlier) processed with `o`, the budget clock `clock` (nullptr: steady clock).
struct BudgetFrame {
  slam::FrameStats stats;
  std::vector<ActiveSearchDataManager::FrameMatch> matches;
  int searches = 0;
  math::Pose pose;
};
BudgetFrame process_with_budget(ActiveSearchOptions o, BudgetClock* clock) {
  OutlierScene s;
  Rig rig(s.T0);
  ActiveSearchDataManager dm(o, rig.map_manager, 320, 240, 11);
  init_known_depth_map(rig, dm, s.img0, 0.03, 0.01);  // frame 0 (before the clock is set: no search there)
  dm.set_budget_clock(clock);
  RawImage raw;
  raw.image = s.img1.view();
  BudgetFrame f;
  dm.process(*rig.map, *rig.sensor, raw, 1, f.stats);
  f.matches = dm.last_frame();
  f.searches = dm.last_frame_searches();
  f.pose = rig.robot->pose();
  return f;
}

TEST(ActiveSearchBudget, OffTheClockIsNeverReadAndTheFrameIsUnchanged) {
  SteppingClock clock(1.0);
  const BudgetFrame plain = process_with_budget(test_options(), nullptr);
  const BudgetFrame clocked = process_with_budget(test_options(), &clock);
  EXPECT_EQ(clock.reads(), 0);
  EXPECT_FALSE(clocked.stats.budget_hit);
  EXPECT_EQ(clocked.stats.budget_skipped, 0);
  EXPECT_EQ(clocked.searches, plain.searches);
  EXPECT_EQ(clocked.stats.updated, plain.stats.updated);
  EXPECT_EQ(clocked.pose.p, plain.pose.p);
  EXPECT_GT(clocked.stats.time_search_ms, 0.0);  // measured by the steady clock when off
}

TEST(ActiveSearchBudget, PlainSearchStopsAfterTheSearchesTheBudgetAllowsInInformationOrder) {
  // Without RANSAC every search is a landmark's. Readings: 0 at the start, k before search k: with a budget of 10.5
  // steps, searches 1..10 start, the 11th reading (11 >= 10.5) spends the budget, the end reads 12.
  ActiveSearchOptions o = test_options();
  o.ransac_ntries = 0;
  o.time_budget_ms = 10.5;
  SteppingClock clock(1.0);
  const BudgetFrame f = process_with_budget(o, &clock);
  ASSERT_GE(f.stats.visible, 14);
  EXPECT_EQ(f.searches, 10);
  EXPECT_EQ(f.stats.searched, 10);
  EXPECT_TRUE(f.stats.budget_hit);
  EXPECT_EQ(f.stats.budget_skipped, f.stats.visible - 10);
  EXPECT_EQ(clock.reads(), 13);
  EXPECT_EQ(f.stats.time_search_ms, 12.0);
  EXPECT_GE(f.stats.updated, 8);  // what was matched is corrected
  // The searched landmarks are the 10 of largest det S at the frame's first prediction.
  double min_searched = std::numeric_limits<double>::infinity(), max_skipped = 0.0;
  for (const auto& m : f.matches) {
    const double det = m.S.determinant();
    if (m.searched) min_searched = std::min(min_searched, det);
    else max_skipped = std::max(max_skipped, det);
  }
  EXPECT_GE(min_searched, max_skipped);
}

TEST(ActiveSearchBudget, CutDuringRansacTheBestSupportIsStillCorrected) {
  // One hypothesis (a full-ellipse search) and its support (box searches) use the 11 searches 11.5 steps allow;
  // no second hypothesis starts and stage 3 searches nothing, but the support set found is corrected.
  ActiveSearchOptions o = test_options();
  o.time_budget_ms = 11.5;
  SteppingClock clock(1.0);
  const BudgetFrame f = process_with_budget(o, &clock);
  EXPECT_EQ(f.searches, 11);
  EXPECT_TRUE(f.stats.budget_hit);
  EXPECT_GE(f.stats.ransac_inliers, 5);
  EXPECT_EQ(f.stats.updated, f.stats.ransac_inliers);
  EXPECT_GT(f.stats.budget_skipped, 0);
  EXPECT_EQ(f.stats.budget_skipped + f.stats.searched, f.stats.visible);
  // A larger budget searches more.
  o.time_budget_ms = 30.5;
  SteppingClock clock30(1.0);
  const BudgetFrame g = process_with_budget(o, &clock30);
  EXPECT_EQ(g.searches, 30);
  EXPECT_GT(g.stats.searched, f.stats.searched);
}

TEST(ActiveSearchBudget, TheBudgetKeyIsRangeChecked) {
  EXPECT_EQ(config_error_of("search: {time_budget_ms: -1}"),
            "cfg.yaml/search: time_budget_ms = -1 must be 0 (off) or in (0, 10000] ms");
  EXPECT_EQ(config_error_of("search: {time_budget_ms: 0.25}"), "(no error)");
  EXPECT_EQ(config_error_of("search: {ransac_confidence: 1}"),
            "cfg.yaml/search: ransac_confidence = 1 must be 0 (off) or in (0, 1)");
  ActiveSearchOptions o;
  o.time_budget_ms = 0.25;
  YAML::Node n = o.to_yaml();
  EXPECT_EQ(n["time_budget_ms"].as<double>(), 0.25);
}

// A change of the map's unit of length (slam::Map::scale_lengths) moves the views of the patches of the landmarks
// the manager's sensor made, also when another holder shares a landmark's descriptor (then copied, the holder's
// own left as it was); landmarks another sensor made are not its business.
TEST(ActiveSearch, PatchViewsFollowAChangeOfTheMapsUnitOfLength) {
  Rig rig(math::Pose{Eigen::Quaterniond::Identity(), Eigen::Vector3d(1.0, 2.0, 0.5)});
  ActiveSearchDataManager dm(test_options(), rig.map_manager, 320, 240, 11);
  const auto with_view = [&](const Eigen::Vector3d& p, int sensor_id) {
    slam::Landmark* l = slam::init_ahp_landmark(*rig.map, *rig.sensor, {160, 120}, 1.0, models::AhpPrior{}, 0);
    EXPECT_NE(l, nullptr);
    auto d = std::make_shared<PointDescriptor>();
    d->T_WS0.p = p;
    l->descriptor = PointDescriptorPtr(d);
    l->sensor_created = sensor_id;
    return l;
  };
  slam::Landmark* own = with_view({1.0, 2.0, 0.5}, rig.sensor->id());
  slam::Landmark* shared = with_view({3.0, -1.0, 0.0}, rig.sensor->id());
  slam::Landmark* foreign = with_view({5.0, 5.0, 5.0}, rig.sensor->id() + 1);
  const PointDescriptorPtr holder = std::any_cast<PointDescriptorPtr>(shared->descriptor);
  const Eigen::Vector3d centre(1.0, 0.0, 0.0);
  dm.scale_lengths(*rig.map, *rig.sensor, 0.5, centre);
  EXPECT_LT((point_descriptor(*own)->T_WS0.p - Eigen::Vector3d(1.0, 1.0, 0.25)).norm(), 1e-15);
  EXPECT_LT((point_descriptor(*shared)->T_WS0.p - Eigen::Vector3d(2.0, -0.5, 0.0)).norm(), 1e-15);
  EXPECT_EQ(holder->T_WS0.p, Eigen::Vector3d(3.0, -1.0, 0.0));
  EXPECT_EQ(point_descriptor(*foreign)->T_WS0.p, Eigen::Vector3d(5.0, 5.0, 5.0));
}

}  // namespace
}  // namespace rtslam::strategies
