// The map manager's policies (map_policies.hpp), on a small map whose robot is turned by hand and whose observation
// counters are set as the data manager sets them (visible: last_visible_frame; searched, matched, updated:
// last_updated_frame): the global policy keeps landmarks out of view, the visual-odometry policy forgets those not
// updated for forget_after_frames and keeps those tracked, the map never holds more than map_size rows, a nearly
// full map drops the landmarks unseen the longest, and AHP landmarks become Euclidean exactly when their linearity
// index is below the threshold.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iterator>
#include <map>
#include <set>
#include <vector>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/strategies/active_search.hpp"
#include "rtslam/strategies/map_policies.hpp"
#include "strategies/strategy_rig.hpp"

namespace rtslam::strategies {
namespace {

using testing::StrategyRig;
using testing::yaw;
using Policy = MapPolicyOptions::Policy;

/// The data manager's bookkeeping for one frame: every visible landmark is marked visible, searched, matched and
/// used in an update, unless listed in `missed` (searched, not matched) or `gated` (matched, gated out).
void track(StrategyRig& rig, long frame, const std::set<int>& missed = {}, const std::set<int>& gated = {}) {
  for (const auto& l : rig.map->landmarks()) {
    if (!rig.visible(*l)) continue;
    auto& c = rig.obs(*l).counters;
    c.last_visible_frame = frame;
    ++c.searched;
    if (missed.count(l->id()) || gated.count(l->id())) ++c.failed;
    if (missed.count(l->id())) continue;
    ++c.matched;
    if (gated.count(l->id())) continue;
    ++c.updated;
    c.last_updated_frame = frame;
  }
}

std::set<int> ids(const slam::Map& map) {
  std::set<int> s;
  for (const auto& l : map.landmarks()) s.insert(l->id());
  return s;
}

/// Places landmarks at `pixels` seen from yaw `yaw_rad`, returns their ids; the robot is left at that yaw.
std::set<int> place_group(StrategyRig& rig, double yaw_rad, const std::vector<Eigen::Vector2d>& pixels, long frame) {
  rig.set_pose(Eigen::Vector3d::Zero(), yaw(yaw_rad));
  std::set<int> out;
  for (const auto& z : pixels) {
    slam::Landmark* l = rig.place(z, frame);
    EXPECT_NE(l, nullptr);
    if (l) out.insert(l->id());
  }
  return out;
}

const std::vector<Eigen::Vector2d> kCentre = {{140, 100}, {180, 140}, {150, 60}, {170, 180}, {135, 130}, {185, 90}};
const std::vector<Eigen::Vector2d> kRight = {{290, 60}, {300, 120}, {295, 190}};  // ~29° right of the axis

/// A scene: the centre group and the right group seen from yaw 0, a back group seen from yaw π; all at frame 0.
struct Scene {
  StrategyRig rig;
  std::set<int> centre, right, back;
  Scene() {
    back = place_group(rig, M_PI, kCentre, 0);
    centre = place_group(rig, 0.0, kCentre, 0);
    right = place_group(rig, 0.0, kRight, 0);
  }
  /// Yaw for frame f: jitter around 0 until `turn_frame`, then around −0.35 rad (the right group leaves the view).
  double yaw_at(long f, long turn_frame, Rng& rng) const {
    return (f < turn_frame ? 0.0 : -0.35) + randu(rng, -0.02, 0.02);
  }
  bool all_in(const std::set<int>& group, bool expect_visible) {
    for (int id : group) {
      slam::Landmark* l = rig.map->find_landmark(id);
      if (!l || rig.visible(*l) != expect_visible) return false;
    }
    return true;
  }
};

TEST(GlobalPolicy, KeepsLandmarksOutOfViewForAnyNumberOfFrames) {
  Scene s;
  PolicyMapManager mm{MapPolicyOptions{}};  // global, forget_unseen_after_frames 0, map far from full
  Rng rng(1);
  constexpr long kTurn = 100, kFrames = 3000;
  for (long f = 1; f <= kFrames; ++f) {
    s.rig.set_pose(Eigen::Vector3d::Zero(), yaw(s.yaw_at(f, kTurn, rng)));
    ASSERT_TRUE(s.all_in(s.back, false)) << "frame " << f;
    ASSERT_TRUE(s.all_in(s.right, f < kTurn)) << "frame " << f;
    track(s.rig, f);
    slam::FrameStats stats;
    mm.manage(*s.rig.map, *s.rig.sensor, f, stats);
    ASSERT_EQ(stats.removed, 0) << "frame " << f;
  }
  EXPECT_EQ(s.rig.map->landmarks().size(), 2 * kCentre.size() + kRight.size());
  // Turning round, the landmarks mapped 3000 frames ago are there to be seen again.
  s.rig.set_pose(Eigen::Vector3d::Zero(), yaw(M_PI));
  EXPECT_TRUE(s.all_in(s.back, true));
}

TEST(GlobalPolicy, ForgetsLandmarksUnseenForForgetUnseenAfterFramesWhenSet) {
  Scene s;
  MapPolicyOptions o;
  o.forget_unseen_after_frames = 50;
  PolicyMapManager mm{o};
  Rng rng(2);
  constexpr long kTurn = 30;
  for (long f = 1; f <= 200; ++f) {
    s.rig.set_pose(Eigen::Vector3d::Zero(), yaw(s.yaw_at(f, kTurn, rng)));
    track(s.rig, f);
    slam::FrameStats stats;
    mm.manage(*s.rig.map, *s.rig.sensor, f, stats);
    const std::set<int> now = ids(*s.rig.map);
    // back: last visible at creation (frame 0); right: last visible at kTurn − 1.
    for (int id : s.back) EXPECT_EQ(now.count(id) == 1, f <= 50) << "back landmark " << id << ", frame " << f;
    for (int id : s.right)
      EXPECT_EQ(now.count(id) == 1, f <= kTurn - 1 + 50) << "right landmark " << id << ", frame " << f;
    for (int id : s.centre) EXPECT_EQ(now.count(id), 1u) << "centre landmark " << id << ", frame " << f;
  }
}

TEST(GlobalPolicy, RemovesLandmarksWithAPoorMatchOrInlierRecord) {
  Scene s;
  MapPolicyOptions o;  // min_searches_to_judge 10, min_match_ratio 0.5, min_inlier_ratio 0.5
  PolicyMapManager mm{o};
  auto it = s.centre.begin();
  const int bad = *it++, borderline = *it++, inconsistent = *it++, consistent_enough = *it++;
  for (long f = 1; f <= 40; ++f) {
    // `bad` is missed 3 frames in 5 (match ratio 0.4), `borderline` every other frame (0.5: kept); `inconsistent`
    // is matched every frame but gated out 3 frames in 5 (inlier ratio 0.4), `consistent_enough` every other frame.
    std::set<int> missed, gated;
    if (f % 5 < 3) missed.insert(bad), gated.insert(inconsistent);
    if (f % 2 == 0) missed.insert(borderline), gated.insert(consistent_enough);
    track(s.rig, f, missed, gated);
    slam::FrameStats stats;
    mm.manage(*s.rig.map, *s.rig.sensor, f, stats);
    const bool judged = f >= o.min_searches_to_judge;
    EXPECT_EQ(s.rig.map->find_landmark(bad) == nullptr, judged) << "frame " << f;
    EXPECT_EQ(s.rig.map->find_landmark(inconsistent) == nullptr, judged) << "frame " << f;
    EXPECT_NE(s.rig.map->find_landmark(borderline), nullptr) << "frame " << f;
    EXPECT_NE(s.rig.map->find_landmark(consistent_enough), nullptr) << "frame " << f;
  }
  EXPECT_EQ(s.rig.map->landmarks().size(), 2 * kCentre.size() + kRight.size() - 2);
}

TEST(VisualOdometryPolicy, ForgetsLandmarksNotUpdatedForForgetAfterFramesAndKeepsTrackedOnes) {
  Scene s;
  MapPolicyOptions o;
  o.policy = Policy::VisualOdometry;
  o.forget_after_frames = 60;
  PolicyMapManager mm{o};
  Rng rng(3);
  constexpr long kTurn = 100;
  for (long f = 1; f <= 1000; ++f) {
    s.rig.set_pose(Eigen::Vector3d::Zero(), yaw(s.yaw_at(f, kTurn, rng)));
    ASSERT_TRUE(s.all_in(s.centre, true)) << "frame " << f;
    track(s.rig, f);
    slam::FrameStats stats;
    mm.manage(*s.rig.map, *s.rig.sensor, f, stats);
    const std::set<int> now = ids(*s.rig.map);
    // back: never updated, created at frame 0; right: last updated at kTurn − 1.
    for (int id : s.back) ASSERT_EQ(now.count(id) == 1, f <= 60) << "back landmark " << id << ", frame " << f;
    for (int id : s.right)
      ASSERT_EQ(now.count(id) == 1, f <= kTurn - 1 + 60) << "right landmark " << id << ", frame " << f;
    for (int id : s.centre) ASSERT_EQ(now.count(id), 1u) << "centre landmark " << id << ", frame " << f;
  }
}

TEST(VisualOdometryPolicy, ForgetsALandmarkInViewThatIsNeverUpdated) {
  Scene s;
  MapPolicyOptions o;
  o.policy = Policy::VisualOdometry;
  o.forget_after_frames = 20;
  o.min_searches_to_judge = 1000;  // the match-ratio rule out of the way
  PolicyMapManager mm{o};
  const int lost = *s.centre.begin();
  for (long f = 1; f <= 30; ++f) {
    track(s.rig, f, {lost});  // visible, searched, never matched
    slam::FrameStats stats;
    mm.manage(*s.rig.map, *s.rig.sensor, f, stats);
    EXPECT_EQ(s.rig.map->find_landmark(lost) != nullptr, f <= 20) << "frame " << f;
  }
}

// ---------------------------------------------------------------------------------------------------------------
// Map size.

int robot_rows(const StrategyRig& rig) { return rig.map->state().block(rig.robot->block()).tangent_size(); }

// A long randomized run: the robot turns at random (landmarks leave and come back), some searches fail, and every
// frame a random number of landmarks is proposed at random pixels, added only when has_room says so. The rows in
// use never exceed map_size, and both limits were reached: additions were refused and landmarks evicted.
TEST(MapSize, IsNeverExceededOverARandomizedRun) {
  for (Policy policy : {Policy::Global, Policy::VisualOdometry}) {
    StrategyRig rig;
    MapPolicyOptions o;
    o.policy = policy;
    o.map_size = robot_rows(rig) + 7 * 20 + 3;  // not a multiple of a landmark's size
    o.evict_rows = 35;
    o.evict_min_unseen_frames = 5;
    PolicyMapManager mm{o};
    Rng rng(policy == Policy::Global ? 31 : 32);
    double yaw_rad = 0.0;
    int added = 0, refused = 0, evicted = 0, removed = 0;
    for (long f = 0; f < 1500; ++f) {
      yaw_rad += randu(rng, -0.15, 0.15);
      rig.set_pose(Eigen::Vector3d::Zero(), yaw(yaw_rad));
      std::set<int> missed;
      for (const auto& l : rig.map->landmarks())
        if (randu(rng, 0, 1) < 0.2) missed.insert(l->id());
      track(rig, f, missed);
      const int proposals = static_cast<int>(randu(rng, 0, 12));
      for (int k = 0; k < proposals; ++k) {
        if (!mm.has_room(*rig.map, 7)) {
          ++refused;
          continue;
        }
        ASSERT_NE(rig.place({randu(rng, 10, 310), randu(rng, 10, 230)}, f), nullptr);
        ++added;
        ASSERT_LE(rig.map->state().tangent_used(), o.map_size) << "frame " << f << " after an addition";
      }
      slam::FrameStats stats;
      mm.manage(*rig.map, *rig.sensor, f, stats);
      ASSERT_LE(rig.map->state().tangent_used(), o.map_size) << "frame " << f << " after manage";
      evicted += stats.evicted;
      removed += stats.removed;
    }
    EXPECT_GT(added, 500);
    EXPECT_GT(refused, 100) << "the map was never full";
    EXPECT_GT(evicted, 50) << "eviction never ran";
    EXPECT_GT(removed, evicted) << "the other removal rules never ran";
  }
}

// map_size is a budget per robot: a second robot in the map (several robots in one world) doubles the rows its
// landmarks may take, so that each robot keeps as many landmarks as alone.
TEST(MapSize, IsABudgetPerRobotInTheMap) {
  StrategyRig rig(filter::StateOptions{.tangent_capacity = 200});
  MapPolicyOptions o;
  o.map_size = robot_rows(rig) + 7 * 5;
  o.evict_rows = 0;
  PolicyMapManager mm{o};
  auto fill = [&] {
    int added = 0;
    for (int k = 0; mm.has_room(*rig.map, 7) && k < 100; ++k) {
      EXPECT_NE(rig.place({100.0 + k, 120.0}, 0), nullptr);
      ++added;
    }
    return added;
  };
  EXPECT_EQ(mm.limit(*rig.map), o.map_size);
  EXPECT_EQ(fill(), 5);
  auto r2 = std::make_unique<slam::ConstantVelocityRobot>(models::ConstantVelocityParams{});
  r2->add_sensor(std::make_unique<slam::PinholeSensor>("cam2", support::qvga_camera(), math::Pose::identity()));
  Eigen::VectorXd x0 = Eigen::VectorXd::Zero(13);
  x0.segment<4>(3) = math::quat_to_wxyz(Eigen::Quaterniond::Identity());
  rig.map->add_robot(std::move(r2), x0, Eigen::MatrixXd::Zero(12, 12), 0);
  EXPECT_EQ(mm.limit(*rig.map), 2 * o.map_size);
  EXPECT_EQ(fill(), 5);  // the second robot's own budget: its block and five more landmarks
  EXPECT_EQ(rig.map->state().tangent_used(), 2 * o.map_size);
}

// has_room is what the data manager asks before each initialization: with a small map_size, a run of the active
// search over a textured image fills the map up to the limit and not beyond.
TEST(MapSize, TheDataManagerHonoursHasRoom) {
  StrategyRig rig;
  MapPolicyOptions o;
  o.map_size = robot_rows(rig) + 7 * 15 + 4;
  o.evict_rows = 0;
  PolicyMapManager mm{o};
  Rng tex_rng(4);
  vision::Image img(320, 240, 128);
  for (int k = 0; k < 600; ++k) {
    const int w = static_cast<int>(randu(tex_rng, 4, 24)), h = static_cast<int>(randu(tex_rng, 4, 24));
    const int x = static_cast<int>(randu(tex_rng, 0, 320 - w)), y = static_cast<int>(randu(tex_rng, 0, 240 - h));
    const auto grey = static_cast<std::uint8_t>(randu(tex_rng, 15, 240));
    for (int v = y; v < y + h; ++v)
      for (int u = x; u < x + w; ++u) img.at(u, v) = grey;
  }
  ActiveSearchDataManager dm(ActiveSearchOptions{}, mm, 320, 240, 5);
  RawImage raw;
  raw.image = img.view();
  int initialized = 0;
  for (long f = 0; f < 4; ++f) {
    slam::FrameStats stats;
    dm.process(*rig.map, *rig.sensor, raw, f, stats);
    initialized += stats.initialized;
    EXPECT_LE(rig.map->state().tangent_used(), o.map_size) << "frame " << f;
  }
  EXPECT_EQ(initialized, 15);
  EXPECT_EQ(rig.map->state().tangent_used(), robot_rows(rig) + 7 * 15);
}

// ---------------------------------------------------------------------------------------------------------------
// Eviction: ten AHP landmarks out of view with chosen last-visible frames (−1: never visible, counts from its
// creation at frame 0); at frame 100 with evict_min_unseen_frames 20, the candidates are those last visible at
// frame 80 or before, dropped longest-unseen first (ties: the lower id) until evict_rows rows are free.

struct EvictionScene {
  StrategyRig rig;
  std::vector<long> last_visible = {50, 10, 95, 10, 30, -1, 99, 85, 60, 5};
  std::vector<int> id;
  EvictionScene() {
    Rng rng(6);
    rig.set_pose(Eigen::Vector3d::Zero(), yaw(M_PI));
    for (size_t i = 0; i < last_visible.size(); ++i) {
      slam::Landmark* l = rig.place({randu(rng, 20, 300), randu(rng, 20, 220)}, 0);
      rig.obs(*l).counters.last_visible_frame = last_visible[i];
      id.push_back(l->id());
    }
    rig.set_pose(Eigen::Vector3d::Zero(), yaw(0.0));  // all out of view
    for (const auto& l : rig.map->landmarks()) EXPECT_FALSE(rig.visible(*l));
  }
  int rows() const { return rig.map->state().tangent_used(); }
  /// The ids the documented criterion drops, computed here from the counters.
  std::set<int> expected_evicted(const MapPolicyOptions& o, long frame) const {
    std::vector<std::pair<long, int>> cand;
    for (size_t i = 0; i < id.size(); ++i) {
      const long lv = std::max(0L, last_visible[i]);
      if (frame - lv >= o.evict_min_unseen_frames) cand.emplace_back(lv, id[i]);
    }
    std::sort(cand.begin(), cand.end());
    std::set<int> out;
    int used = rows();
    for (const auto& [lv, i] : cand) {
      if (used + o.evict_rows <= o.map_size) break;
      out.insert(i);
      used -= 7;
    }
    return out;
  }
};

TEST(Eviction, DropsTheLongestUnseenLandmarksUntilEvictRowsAreFree) {
  EvictionScene s;
  MapPolicyOptions o;
  o.map_size = s.rows();  // full
  o.evict_rows = 21;      // three AHP landmarks
  o.evict_min_unseen_frames = 20;
  PolicyMapManager mm{o};
  const std::set<int> expected = s.expected_evicted(o, 100);
  // Never visible (frame 0), last visible at 5, then the lower id of the two last visible at 10.
  ASSERT_EQ(expected, (std::set<int>{s.id[5], s.id[9], s.id[1]}));
  const std::set<int> before = ids(*s.rig.map);
  slam::FrameStats stats;
  mm.manage(*s.rig.map, *s.rig.sensor, 100, stats);
  const std::set<int> after = ids(*s.rig.map);
  std::set<int> gone;
  std::set_difference(before.begin(), before.end(), after.begin(), after.end(), std::inserter(gone, gone.end()));
  EXPECT_EQ(gone, expected);
  EXPECT_EQ(stats.evicted, 3);
  EXPECT_EQ(stats.removed, 3);
  EXPECT_LE(s.rows() + o.evict_rows, o.map_size);
}

TEST(Eviction, NeverDropsRecentlyVisibleLandmarksEvenIfRowsStayShort) {
  EvictionScene s;
  MapPolicyOptions o;
  o.map_size = s.rows();
  o.evict_rows = 63;  // nine landmarks, but only seven are candidates
  o.evict_min_unseen_frames = 20;
  PolicyMapManager mm{o};
  slam::FrameStats stats;
  mm.manage(*s.rig.map, *s.rig.sensor, 100, stats);
  EXPECT_EQ(ids(*s.rig.map), (std::set<int>{s.id[2], s.id[6], s.id[7]}));  // last visible at 95, 99, 85
  EXPECT_EQ(stats.evicted, 7);
}

TEST(Eviction, DoesNothingWhileEvictRowsAreFree) {
  EvictionScene s;
  MapPolicyOptions o;
  o.map_size = s.rows() + 21;
  o.evict_rows = 21;
  o.evict_min_unseen_frames = 20;
  PolicyMapManager mm{o};
  slam::FrameStats stats;
  mm.manage(*s.rig.map, *s.rig.sensor, 100, stats);
  EXPECT_EQ(stats.removed, 0);
  EXPECT_EQ(s.rig.map->landmarks().size(), 10u);
  // One row fewer and the longest-unseen landmark goes.
  o.map_size -= 1;
  PolicyMapManager tight{o};
  tight.manage(*s.rig.map, *s.rig.sensor, 100, stats);
  EXPECT_EQ(stats.evicted, 1);
  EXPECT_EQ(s.rig.map->find_landmark(s.id[5]), nullptr);
}

TEST(Eviction, IsOffWhenEvictWhenFullIsFalse) {
  EvictionScene s;
  MapPolicyOptions o;
  o.map_size = s.rows();
  o.evict_rows = 21;
  o.evict_when_full = false;
  PolicyMapManager mm{o};
  slam::FrameStats stats;
  mm.manage(*s.rig.map, *s.rig.sensor, 100, stats);
  EXPECT_EQ(stats.removed, 0);
}

// ---------------------------------------------------------------------------------------------------------------
// Reparametrization: AHP landmarks 2 m ahead of the camera (at their anchor: cos α = 1, d₁ = d = 1/ρ), their
// covariance set so that the linearity index L_d = 4 σ_d / d = 4 σ_ρ / ρ takes chosen values around the threshold.

TEST(Reparametrization, HappensExactlyWhenTheLinearityIndexIsBelowTheThreshold) {
  for (double threshold : {0.1, 0.3}) {
    StrategyRig rig;
    MapPolicyOptions o;
    o.reparam_threshold = threshold;
    PolicyMapManager mm{o};
    const std::vector<double> targets = {0.01, 0.05, 0.09, 0.11, 0.2, 0.29, 0.31, 0.6, 2.0};
    std::map<int, double> index_of;
    std::map<int, Eigen::Vector3d> position_of;
    Rng rng(7);
    for (double target : targets) {
      slam::Landmark* l = rig.place({randu(rng, 40, 280), randu(rng, 40, 200)}, 0, 2.0);
      ASSERT_NE(l, nullptr);
      const double rho = rig.map->state().mean(l->block())[6];
      Eigen::Matrix<double, 7, 1> var = Eigen::Matrix<double, 7, 1>::Constant(1e-14);
      var[6] = std::pow(target * rho / 4.0, 2);
      rig.map->state().cov(l->block(), l->block()) = var.asDiagonal().toDenseMatrix();
      const Eigen::Vector3d p_WS = rig.sensor->pose_in_world(rig.map->state().mean_vector()).p;
      index_of[l->id()] = slam::linearity_index(*rig.map, *l, p_WS);
      ASSERT_NEAR(index_of[l->id()], target, 1e-3 * target);
      position_of[l->id()] = l->position(rig.map->state().mean_vector());
      auto& c = rig.obs(*l).counters;  // updated once in this frame
      c.searched = c.matched = c.updated = 1;
      c.last_visible_frame = c.last_updated_frame = 1;
    }
    // An AHP landmark never used in an update keeps its parametrization whatever its index (its covariance is
    // still the prior's).
    slam::Landmark* fresh = rig.place({160, 120}, 1, 2.0);
    const double rho = rig.map->state().mean(fresh->block())[6];
    Eigen::Matrix<double, 7, 1> var = Eigen::Matrix<double, 7, 1>::Constant(1e-14);
    var[6] = std::pow(0.01 * rho / 4.0, 2);
    rig.map->state().cov(fresh->block(), fresh->block()) = var.asDiagonal().toDenseMatrix();
    rig.obs(*fresh).counters.last_visible_frame = 1;
    const int fresh_id = fresh->id();

    int expected = 0;
    for (const auto& [id, index] : index_of) expected += index < threshold;
    for (long f = 1; f <= 5; ++f) {  // and not at later frames either
      slam::FrameStats stats;
      mm.manage(*rig.map, *rig.sensor, f, stats);
      EXPECT_EQ(stats.reparametrized, f == 1 ? expected : 0) << "threshold " << threshold << ", frame " << f;
      EXPECT_EQ(stats.removed, 0);
    }
    for (const auto& [id, index] : index_of) {
      const slam::Landmark* l = rig.map->find_landmark(id);
      ASSERT_NE(l, nullptr);
      EXPECT_EQ(l->type() == slam::LandmarkType::EuclideanPoint, index < threshold)
          << "index " << index << ", threshold " << threshold;
      EXPECT_LT((l->position(rig.map->state().mean_vector()) - position_of[id]).norm(), 1e-9);
    }
    EXPECT_EQ(rig.map->find_landmark(fresh_id)->type(), slam::LandmarkType::AhpPoint);
  }
}

TEST(MapPolicyOptions, RejectsBadValues) {
  MapPolicyOptions o;
  o.map_size = 0;
  EXPECT_THROW(o.validate(), ConfigError);
  o = {};
  o.evict_rows = o.map_size + 1;
  EXPECT_THROW(o.validate(), ConfigError);
  o = {};
  o.forget_after_frames = 0;
  EXPECT_THROW(PolicyMapManager{o}, ConfigError);
}

}  // namespace
}  // namespace rtslam::strategies
