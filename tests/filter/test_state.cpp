#include "rtslam/filter/state.hpp"

#include <cstring>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/filter/kernels.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::filter {
namespace {

MatrixXd random_spd(int n, Rng& rng, double scale = 1.0) {
  MatrixXd A(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) A(i, j) = randn(rng);
  return scale * (A * A.transpose() / n + 0.1 * MatrixXd::Identity(n, n));
}

MatrixXd random_matrix(int r, int c, Rng& rng) {
  MatrixXd A(r, c);
  for (int i = 0; i < r; ++i)
    for (int j = 0; j < c; ++j) A(i, j) = randn(rng);
  return A;
}

// A state of Euclidean blocks with a full, correlated joint covariance; also returns the dense copy.
struct DenseMirror {
  std::vector<BlockId> ids;
  std::vector<int> sizes;
  VectorXd x;
  MatrixXd P;
  int offset_of(size_t k) const {
    int o = 0;
    for (size_t i = 0; i < k; ++i) o += sizes[i];
    return o;
  }
};

DenseMirror fill_linear_state(State& s, const std::vector<int>& sizes, Rng& rng) {
  DenseMirror d;
  d.sizes = sizes;
  int n = 0;
  for (int sz : sizes) n += sz;
  d.x = VectorXd(n);
  for (int i = 0; i < n; ++i) d.x[i] = randn(rng);
  d.P = random_spd(n, rng);
  int off = 0;
  for (int sz : sizes) {
    const auto id = s.add_block(BlockLayout::euclidean(sz), d.x.segment(off, sz), MatrixXd::Identity(sz, sz));
    EXPECT_TRUE(id.has_value());
    d.ids.push_back(*id);
    off += sz;
  }
  for (size_t a = 0; a < sizes.size(); ++a)
    for (size_t b = 0; b < sizes.size(); ++b)
      s.cov(d.ids[a], d.ids[b]) = d.P.block(d.offset_of(a), d.offset_of(b), sizes[a], sizes[b]);
  return d;
}

// The dense mirror of the blocks of d that `keep` lists (the others removed from s).
DenseMirror mirror_of_kept(const State& s, const DenseMirror& d, const std::vector<size_t>& keep) {
  DenseMirror r;
  int n = 0;
  for (size_t k : keep) {
    r.ids.push_back(d.ids[k]);
    r.sizes.push_back(d.sizes[k]);
    n += d.sizes[k];
  }
  r.x = VectorXd(n);
  r.P = MatrixXd(n, n);
  for (size_t a = 0; a < keep.size(); ++a) {
    r.x.segment(r.offset_of(a), r.sizes[a]) = s.mean(r.ids[a]);
    for (size_t b = 0; b < keep.size(); ++b)
      r.P.block(r.offset_of(a), r.offset_of(b), r.sizes[a], r.sizes[b]) = s.cov(r.ids[a], r.ids[b]);
  }
  return r;
}

void expect_matches_dense(const State& s, const DenseMirror& d, double tol) {
  for (size_t a = 0; a < d.ids.size(); ++a) {
    EXPECT_LT((s.mean(d.ids[a]) - d.x.segment(d.offset_of(a), d.sizes[a])).norm(), tol) << "block " << a;
    for (size_t b = 0; b < d.ids.size(); ++b) {
      const MatrixXd ref = d.P.block(d.offset_of(a), d.offset_of(b), d.sizes[a], d.sizes[b]);
      EXPECT_LT((s.cov(d.ids[a], d.ids[b]) - ref).norm(), tol) << "blocks " << a << "," << b;
    }
  }
}

TEST(State, MatchesClosedFormKalmanFilterOnLinearGaussianProblem) {
  Rng rng(42);
  State s;
  DenseMirror d = fill_linear_state(s, {3, 2, 4, 1, 5}, rng);
  const int n = static_cast<int>(d.x.size());
  for (int step = 0; step < 5; ++step) {
    // Predict block 2 (4-dim): x_b ← F x_b + u, P ← F P Fᵀ + Q on that block.
    const MatrixXd F = MatrixXd::Identity(4, 4) + 0.3 * random_matrix(4, 4, rng);
    const MatrixXd Q = random_spd(4, rng, 0.1);
    const VectorXd u = random_matrix(4, 1, rng);
    s.mean(d.ids[2]) = F * s.mean(d.ids[2]) + u;
    s.predict(d.ids[2], F, Q);
    MatrixXd Ff = MatrixXd::Identity(n, n);
    const int o2 = d.offset_of(2);
    Ff.block(o2, o2, 4, 4) = F;
    MatrixXd Qf = MatrixXd::Zero(n, n);
    Qf.block(o2, o2, 4, 4) = Q;
    d.x.segment(o2, 4) = F * d.x.segment(o2, 4) + u;
    d.P = Ff * d.P * Ff.transpose() + Qf;
    expect_matches_dense(s, d, 1e-9);

    // Correct with a 3-row measurement of blocks 0 and 4 (compressed H: 3 x (3 + 5)).
    const std::vector<BlockId> involved = {d.ids[0], d.ids[4]};
    const MatrixXd Hc = random_matrix(3, 8, rng);
    const MatrixXd R = random_spd(3, rng, 0.05);
    const VectorXd z = random_matrix(3, 1, rng);
    MatrixXd Hf = MatrixXd::Zero(3, n);
    Hf.block(0, d.offset_of(0), 3, 3) = Hc.leftCols(3);
    Hf.block(0, d.offset_of(4), 3, 5) = Hc.rightCols(5);
    const VectorXd y = z - Hf * d.x;
    const auto res = s.correct(involved, Hc, y, R);
    ASSERT_TRUE(res.ok()) << to_string(res.status);
    const MatrixXd S = Hf * d.P * Hf.transpose() + R;
    const MatrixXd K = d.P * Hf.transpose() * S.inverse();
    EXPECT_NEAR(res.mahalanobis2, y.dot(S.ldlt().solve(y)), 1e-9);
    d.x += K * y;
    d.P = d.P - K * S * K.transpose();
    expect_matches_dense(s, d, 1e-9);
  }
}

TEST(State, CovarianceStaysExactlySymmetric) {
  Rng rng(3);
  State s;
  DenseMirror d = fill_linear_state(s, {6, 6, 6}, rng);
  const std::vector<BlockId> involved = {d.ids[1]};
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(s.correct(involved, random_matrix(2, 6, rng), random_matrix(2, 1, rng), MatrixXd::Identity(2, 2)).ok());
  }
  const int n = 18;
  const MatrixXd P = s.covariance().topLeftCorner(n, n);
  EXPECT_EQ((P - P.transpose()).cwiseAbs().maxCoeff(), 0.0);
}

TEST(State, BatchedCorrectionEqualsSequentialOnLinearProblem) {
  Rng rng(9);
  State a;
  State b;
  Rng rng_b = rng;
  DenseMirror da = fill_linear_state(a, {4, 3, 3}, rng);
  DenseMirror db = fill_linear_state(b, {4, 3, 3}, rng_b);
  const MatrixXd H1 = random_matrix(2, 7, rng);  // blocks 0,1
  const MatrixXd H2 = random_matrix(2, 7, rng);  // blocks 0,2
  const VectorXd z1 = random_matrix(2, 1, rng);
  const VectorXd z2 = random_matrix(2, 1, rng);
  const MatrixXd R = 0.1 * MatrixXd::Identity(2, 2);
  const auto h = [](const State& s, const DenseMirror& d, const MatrixXd& H, int other) {
    VectorXd x(7);
    x << s.mean(d.ids[0]), s.mean(d.ids[static_cast<size_t>(other)]);
    return VectorXd(H * x);
  };
  // Sequential on a.
  ASSERT_TRUE(a.correct(std::vector<BlockId>{da.ids[0], da.ids[1]}, H1, z1 - h(a, da, H1, 1), R).ok());
  ASSERT_TRUE(a.correct(std::vector<BlockId>{da.ids[0], da.ids[2]}, H2, z2 - h(a, da, H2, 2), R).ok());
  // Batched on b: compressed over blocks {0,1,2}.
  MatrixXd H = MatrixXd::Zero(4, 10);
  H.block(0, 0, 2, 4) = H1.leftCols(4);
  H.block(0, 4, 2, 3) = H1.rightCols(3);
  H.block(2, 0, 2, 4) = H2.leftCols(4);
  H.block(2, 7, 2, 3) = H2.rightCols(3);
  VectorXd y(4);
  y << z1 - h(b, db, H1, 1), z2 - h(b, db, H2, 2);
  MatrixXd R4 = 0.1 * MatrixXd::Identity(4, 4);
  ASSERT_TRUE(b.correct(std::vector<BlockId>{db.ids[0], db.ids[1], db.ids[2]}, H, y, R4).ok());
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_LT((a.mean(da.ids[i]) - b.mean(db.ids[i])).norm(), 1e-9);
    for (size_t j = 0; j < 3; ++j) EXPECT_LT((a.cov(da.ids[i], da.ids[j]) - b.cov(db.ids[i], db.ids[j])).norm(), 1e-9);
  }
}

TEST(State, AddAndRemoveKeepOtherBlocksBitIdentical) {
  Rng rng(5);
  State s(StateOptions{.tangent_capacity = 80});
  DenseMirror d = fill_linear_state(s, {3, 7, 3, 7, 7, 3}, rng);
  const VectorXd x0 = s.mean_vector();
  const MatrixXd P0 = s.covariance();
  // Remove block 1 (7 rows), add a block derived from blocks 0 and 3, then a 3-block into the freed space.
  s.remove_block(d.ids[1]);
  const MatrixXd J = random_matrix(7, 10, rng);
  const std::vector<BlockId> parents = {d.ids[0], d.ids[3]};
  const auto n1 = s.add_block(BlockLayout::euclidean(7), VectorXd::Ones(7), parents, J, MatrixXd::Identity(7, 7));
  ASSERT_TRUE(n1.has_value());
  const auto n2 = s.add_block(BlockLayout::euclidean(3), VectorXd::Ones(3), MatrixXd::Identity(3, 3));
  ASSERT_TRUE(n2.has_value());
  EXPECT_EQ(s.block(*n1).tangent_offset, 3) << "freed rows are reused first";
  for (size_t a : {0u, 2u, 3u, 4u, 5u}) {
    const BlockInfo& ba = s.block(d.ids[a]);
    EXPECT_TRUE((s.mean(d.ids[a]).array() == x0.segment(ba.ambient_offset, ba.ambient_size()).array()).all());
    for (size_t b : {0u, 2u, 3u, 4u, 5u}) {
      const BlockInfo& bb = s.block(d.ids[b]);
      const MatrixXd before = P0.block(ba.tangent_offset, bb.tangent_offset, ba.tangent_size(), bb.tangent_size());
      EXPECT_TRUE((s.cov(d.ids[a], d.ids[b]).array() == before.array()).all()) << a << "," << b;
    }
  }
  // The derived block's covariance follows P_nn = J P_pp Jᵀ + I and P_no = J P_po.
  MatrixXd Ppp(10, 10);
  Ppp << s.cov(d.ids[0], d.ids[0]), s.cov(d.ids[0], d.ids[3]), s.cov(d.ids[3], d.ids[0]), s.cov(d.ids[3], d.ids[3]);
  EXPECT_LT((s.cov(*n1, *n1) - (J * Ppp * J.transpose() + MatrixXd::Identity(7, 7))).norm(), 1e-12);
  MatrixXd Pp4(10, 7);
  Pp4 << s.cov(d.ids[0], d.ids[4]), s.cov(d.ids[3], d.ids[4]);
  EXPECT_LT((s.cov(*n1, d.ids[4]) - J * Pp4).norm(), 1e-12);
  EXPECT_TRUE(s.cov(*n2, d.ids[4]).isZero(0.0));
}

TEST(State, CorrectionTouchingTwoOfFiftyBlocksChangesOnlyCorrelatedOnes) {
  Rng rng(11);
  State s;
  // 50 blocks of 3; blocks 0..9 are mutually correlated, 10..49 are independent of them and of each other.
  std::vector<BlockId> ids;
  for (int i = 0; i < 50; ++i) {
    ids.push_back(*s.add_block(BlockLayout::euclidean(3), random_matrix(3, 1, rng), random_spd(3, rng)));
  }
  const MatrixXd C = random_spd(30, rng);
  for (int a = 0; a < 10; ++a)
    for (int b = 0; b < 10; ++b) s.cov(ids[a], ids[b]) = C.block(3 * a, 3 * b, 3, 3);
  const VectorXd x0 = s.mean_vector();
  const MatrixXd P0 = s.covariance();
  // Observe blocks 2 and 7.
  const std::vector<BlockId> involved = {ids[2], ids[7]};
  const MatrixXd H = random_matrix(2, 6, rng);
  ASSERT_TRUE(s.correct(involved, H, random_matrix(2, 1, rng), 0.01 * MatrixXd::Identity(2, 2)).ok());
  for (int a = 0; a < 50; ++a) {
    const BlockInfo& ba = s.block(ids[a]);
    const bool moved = !(s.mean(ids[a]).array() == x0.segment(ba.ambient_offset, 3).array()).all();
    EXPECT_EQ(moved, a < 10) << "block " << a;
    for (int b = 0; b < 50; ++b) {
      const BlockInfo& bb = s.block(ids[b]);
      const bool changed = !(s.cov(ids[a], ids[b]).array() ==
                             P0.block(ba.tangent_offset, bb.tangent_offset, 3, 3).array()).all();
      EXPECT_EQ(changed, a < 10 && b < 10) << a << "," << b;
    }
  }
}

TEST(State, GatedCorrectionChangesNothing) {
  Rng rng(2);
  State s;
  DenseMirror d = fill_linear_state(s, {2, 2}, rng);
  const VectorXd x0 = s.mean_vector();
  const MatrixXd P0 = s.covariance();
  const std::vector<BlockId> involved = {d.ids[0]};
  const auto res = s.correct(involved, MatrixXd::Identity(2, 2), VectorXd::Constant(2, 100.0),
                             0.01 * MatrixXd::Identity(2, 2), 9.0);
  EXPECT_EQ(res.status, CorrectionResult::Status::Gated);
  EXPECT_GT(res.mahalanobis2, 9.0);
  EXPECT_TRUE((s.mean_vector().array() == x0.array()).all());
  EXPECT_TRUE((s.covariance().array() == P0.array()).all());
}

TEST(State, RefusesUpdateThatWouldMakeAVarianceNonPositive) {
  State s;
  const BlockId a = *s.add_block(BlockLayout::euclidean(2), VectorXd::Zero(2), MatrixXd::Identity(2, 2));
  // Corrupt the covariance into an indefinite matrix: the update would drive var(x1) below zero.
  s.cov(a, a) << 1.0, 2.0, 2.0, 1.0;
  const VectorXd x0 = s.mean_vector();
  const MatrixXd P0 = s.covariance();
  MatrixXd H(1, 2);
  H << 1.0, 0.0;
  const std::vector<BlockId> involved = {a};
  const auto res = s.correct(involved, H, VectorXd::Ones(1), 0.01 * MatrixXd::Identity(1, 1));
  EXPECT_EQ(res.status, CorrectionResult::Status::NonPositiveVariance);
  EXPECT_TRUE((s.mean_vector().array() == x0.array()).all());
  EXPECT_TRUE((s.covariance().array() == P0.array()).all());
  // And a non-positive-definite innovation covariance is refused too.
  const auto res2 = s.correct(involved, H, VectorXd::Ones(1), -5.0 * MatrixXd::Identity(1, 1));
  EXPECT_EQ(res2.status, CorrectionResult::Status::NotPositiveDefinite);
}

TEST(State, MeanCorrectionEqualsTheMeanPartOfCorrect) {
  Rng rng(8);
  State s;
  DenseMirror d = fill_linear_state(s, {3, 4, 2}, rng);
  const std::vector<BlockId> involved = {d.ids[1]};
  const MatrixXd H = random_matrix(2, 4, rng);
  const VectorXd y = random_matrix(2, 1, rng);
  const MatrixXd R = 0.2 * MatrixXd::Identity(2, 2);
  VectorXd dx(s.tangent_capacity());
  ASSERT_TRUE(s.mean_correction(involved, H, y, R, dx).ok());
  VectorXd predicted;
  s.boxplus_all(s.mean_vector(), dx, predicted);
  ASSERT_TRUE(s.correct(involved, H, y, R).ok());
  EXPECT_LT((predicted - s.mean_vector()).norm(), 1e-12);
}

TEST(State, QuaternionBlockIsCorrectedThroughItsRetraction) {
  // A pose-like block [p(3) q]: observe the orientation directly (z = δθ measured around the mean); the mean
  // must move by q ⊗ Exp(K y) and the orientation variance must shrink as in the scalar KF.
  State s;
  const BlockLayout layout = BlockLayout::euclidean(3).then_quaternion();
  VectorXd mean(7);
  mean << 1.0, 2.0, 3.0, math::quat_to_wxyz(math::exp_so3(Eigen::Vector3d(0.1, 0.2, 0.3)));
  const BlockId b = *s.add_block(layout, mean, 0.04 * MatrixXd::Identity(6, 6));
  MatrixXd H = MatrixXd::Zero(3, 6);
  H.rightCols(3).setIdentity();
  const Eigen::Vector3d y(0.02, -0.01, 0.03);
  const std::vector<BlockId> involved = {b};
  ASSERT_TRUE(s.correct(involved, H, y, 0.04 * MatrixXd::Identity(3, 3)).ok());
  const Eigen::Vector3d expected_step = 0.5 * y;  // K = 0.04 / (0.04 + 0.04)
  const auto q_expected = math::boxplus(math::quat_from_wxyz(mean.tail<4>()), expected_step);
  EXPECT_LT((s.mean(b).tail<4>() - math::quat_to_wxyz(q_expected)).norm(), 1e-12);
  EXPECT_TRUE((s.mean(b).head<3>().array() == mean.head<3>().array()).all());
  EXPECT_NEAR(s.cov(b, b)(4, 4), 0.02, 1e-12);
  EXPECT_NEAR(s.cov(b, b)(1, 1), 0.04, 1e-15);
}

TEST(State, FullStateRefusesNewBlocksAndRecoversAfterRemoval) {
  State s(StateOptions{.tangent_capacity = 10});
  const auto a = s.add_block(BlockLayout::euclidean(7), VectorXd::Zero(7), MatrixXd::Identity(7, 7));
  ASSERT_TRUE(a.has_value());
  EXPECT_FALSE(s.add_block(BlockLayout::euclidean(7), VectorXd::Zero(7), MatrixXd::Identity(7, 7)).has_value());
  s.remove_block(*a);
  EXPECT_TRUE(s.add_block(BlockLayout::euclidean(7), VectorXd::Zero(7), MatrixXd::Identity(7, 7)).has_value());
  EXPECT_EQ(s.tangent_used(), 7);
}

// A map that several robots join grows its storage by each one's rows before the run (pipeline/builder.hpp).
TEST(State, ReserveGrowsAnEmptyStateAndRefusesOnceItHoldsBlocks) {
  State s(StateOptions{.tangent_capacity = 10});
  s.reserve(5);  // smaller: nothing changes
  EXPECT_EQ(s.tangent_capacity(), 10);
  s.reserve(20);
  EXPECT_EQ(s.tangent_capacity(), 20);
  const auto a = s.add_block(BlockLayout::euclidean(7), VectorXd::Ones(7), MatrixXd::Identity(7, 7));
  const auto b = s.add_block(BlockLayout::euclidean(7), VectorXd::Ones(7), MatrixXd::Identity(7, 7));
  ASSERT_TRUE(a.has_value() && b.has_value());
  EXPECT_FALSE(s.add_block(BlockLayout::euclidean(7), VectorXd::Zero(7), MatrixXd::Identity(7, 7)).has_value());
  EXPECT_THROW(s.reserve(40), InvariantError);
  EXPECT_EQ(s.tangent_capacity(), 20);
  EXPECT_EQ(s.tangent_used(), 14);
  EXPECT_THROW(State(StateOptions{.tangent_capacity = 10}).reserve(StateOptions::kMaxTangentCapacity + 1), ConfigError);
}

}  // namespace
}  // namespace rtslam::filter

namespace rtslam::filter {
namespace {

TEST(State, ZeroVarianceGaugeRowsStayZeroAndDoNotBlockUpdates) {
  State s;
  // Block a: a gauge (zero covariance); block b: uncertain and observed.
  const BlockId a = *s.add_block(BlockLayout::euclidean(3), Eigen::VectorXd::Zero(3), MatrixXd::Zero(3, 3));
  const BlockId b = *s.add_block(BlockLayout::euclidean(2), Eigen::VectorXd::Zero(2), MatrixXd::Identity(2, 2));
  MatrixXd H(2, 5);
  H << 1, 0, 0, 1, 0, 0, 1, 0, 0, 1;
  const std::vector<BlockId> involved = {a, b};
  ASSERT_TRUE(s.correct(involved, H, Eigen::Vector2d(0.3, -0.2), 0.1 * MatrixXd::Identity(2, 2)).ok());
  EXPECT_TRUE(s.cov(a, a).isZero(0.0));
  EXPECT_TRUE(s.mean(a).isZero(0.0));
  EXPECT_NEAR(s.cov(b, b)(0, 0), 0.1 / 1.1, 1e-12);
}

}  // namespace
}  // namespace rtslam::filter

namespace rtslam::filter {
namespace {

TEST(State, PredictionWithUnitAndSparseRowsIsTheClosedFormAcrossHoles) {
  // predict() skips F's unit rows and sums only the non-zero terms of the others: an inertial-like transition (the
  // last rows the identity's, zeros in the others) on a block between holes (removed blocks) must give the dense
  // F P Fᵀ + Q, leave the unit rows' cross-covariances bit for bit as they were, and write exact mirrors.
  Rng rng(33);
  State s;
  DenseMirror d = fill_linear_state(s, {3, 4, 9, 2, 5, 3}, rng);
  s.remove_block(d.ids[1]);
  s.remove_block(d.ids[4]);
  const std::vector<size_t> keep = {0, 2, 3, 5};
  DenseMirror r = mirror_of_kept(s, d, keep);
  const int n = static_cast<int>(r.x.size());
  // Exactly symmetric, as the filter keeps it (the random start is symmetric to rounding only).
  r.P = (0.5 * (r.P + r.P.transpose())).eval();
  for (size_t a = 0; a < keep.size(); ++a)
    for (size_t b = 0; b < keep.size(); ++b)
      s.cov(r.ids[a], r.ids[b]) = r.P.block(r.offset_of(a), r.offset_of(b), r.sizes[a], r.sizes[b]);
  MatrixXd F = MatrixXd::Identity(9, 9);
  F.topRows(5) += 0.3 * random_matrix(5, 9, rng);
  F(1, 4) = 0.0;  // zeros inside transformed rows
  F(3, 0) = 0.0;
  F.row(2).setZero();  // a row of zeros (a reset) is transformed too
  F(6, 6) = 1.0 - 1e-3;  // not a unit row
  F(0, 0) = 1.0;         // nor is one with a unit diagonal and other terms
  const MatrixXd Q = random_spd(9, rng, 0.01);
  const MatrixXd before = s.cov(r.ids[0], r.ids[1]);  // the rows of block 0 against block 2's
  s.predict(r.ids[1], F, Q);
  MatrixXd Ff = MatrixXd::Identity(n, n);
  Ff.block(r.offset_of(1), r.offset_of(1), 9, 9) = F;
  MatrixXd Qf = MatrixXd::Zero(n, n);
  Qf.block(r.offset_of(1), r.offset_of(1), 9, 9) = Q;
  r.P = Ff * r.P * Ff.transpose() + Qf;
  expect_matches_dense(s, r, 1e-12);
  for (int i : {5, 7, 8}) {  // unit rows: columns 5, 7, 8 of block 0's cross-covariance untouched
    EXPECT_EQ(s.cov(r.ids[0], r.ids[1]).col(i), before.col(i)) << "row " << i;
  }
  EXPECT_NE(s.cov(r.ids[0], r.ids[1]).col(6), before.col(6));
  for (size_t a = 0; a < keep.size(); ++a) {
    const MatrixXd ab = s.cov(r.ids[a], r.ids[1]), ba = s.cov(r.ids[1], r.ids[a]);
    EXPECT_EQ(ab, ba.transpose()) << "blocks " << a << ",1";
  }
}

TEST(State, MatchesClosedFormAcrossSeveralActiveRuns) {
  // Holes in the covariance (removed blocks) split the active rows into runs; the downdate over run pairs must
  // still be the closed-form one.
  Rng rng(21);
  State s;
  DenseMirror d = fill_linear_state(s, {3, 5, 2, 4, 3, 6}, rng);
  s.remove_block(d.ids[1]);
  s.remove_block(d.ids[4]);
  ASSERT_EQ(s.active_runs().size(), 3u);
  // Dense mirror of the remaining blocks 0, 2, 3, 5.
  const std::vector<size_t> keep = {0, 2, 3, 5};
  DenseMirror r = mirror_of_kept(s, d, keep);
  const int n = static_cast<int>(r.x.size());
  for (int step = 0; step < 3; ++step) {
    const std::vector<BlockId> involved = {r.ids[1], r.ids[3]};
    const MatrixXd Hc = random_matrix(4, 8, rng);
    const MatrixXd R = random_spd(4, rng, 0.05);
    const VectorXd y = random_matrix(4, 1, rng);
    MatrixXd Hf = MatrixXd::Zero(4, n);
    Hf.block(0, r.offset_of(1), 4, 2) = Hc.leftCols(2);
    Hf.block(0, r.offset_of(3), 4, 6) = Hc.rightCols(6);
    ASSERT_TRUE(s.correct(involved, Hc, y, R).ok());
    const MatrixXd S = Hf * r.P * Hf.transpose() + R;
    const MatrixXd K = r.P * Hf.transpose() * S.inverse();
    r.x += K * y;
    r.P = r.P - K * S * K.transpose();
    expect_matches_dense(s, r, 1e-9);
    // Prediction of a block in the middle run.
    const MatrixXd F = MatrixXd::Identity(4, 4) + 0.2 * random_matrix(4, 4, rng);
    s.mean(r.ids[2]) = F * s.mean(r.ids[2]);
    s.predict(r.ids[2], F, MatrixXd::Identity(4, 4) * 0.01);
    MatrixXd Ff = MatrixXd::Identity(n, n);
    Ff.block(r.offset_of(2), r.offset_of(2), 4, 4) = F;
    MatrixXd Qf = MatrixXd::Zero(n, n);
    Qf.block(r.offset_of(2), r.offset_of(2), 4, 4) = MatrixXd::Identity(4, 4) * 0.01;
    r.x.segment(r.offset_of(2), 4) = F * r.x.segment(r.offset_of(2), 4);
    r.P = Ff * r.P * Ff.transpose() + Qf;
    expect_matches_dense(s, r, 1e-9);
  }
}

}  // namespace
}  // namespace rtslam::filter

namespace rtslam::filter {
namespace {

StateOptions with_basis(int k) {
  StateOptions o;
  o.tangent_capacity = 60;
  o.nullspace_dim = k;
  return o;
}

TEST(StateObservabilityConstraints, NewBlocksInheritTheBasisThroughTheirJacobian) {
  Rng rng(11);
  State s(with_basis(2));
  const MatrixXd N0 = random_matrix(4, 2, rng);
  const auto a = s.add_block(BlockLayout::euclidean(4), VectorXd::Zero(4), random_spd(4, rng), N0);
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(MatrixXd(s.nullspace(*a)), N0);
  const MatrixXd J = random_matrix(3, 4, rng);
  const BlockId parents[1] = {*a};
  const auto b = s.add_block(BlockLayout::euclidean(3), VectorXd::Zero(3), parents, J, MatrixXd::Identity(3, 3));
  ASSERT_TRUE(b.has_value());
  EXPECT_LT((MatrixXd(s.nullspace(*b)) - J * N0).norm(), 1e-14);
  // An independent prior without a basis has zero rows.
  const auto c = s.add_block(BlockLayout::euclidean(2), VectorXd::Zero(2), MatrixXd::Identity(2, 2));
  EXPECT_EQ(MatrixXd(s.nullspace(*c)), MatrixXd::Zero(2, 2));
}

TEST(StateObservabilityConstraints, ProjectedJacobianAnnihilatesTheBasisAndKeepsTheOrthogonalPart) {
  Rng rng(12);
  const MatrixXd N = random_matrix(9, 3, rng);
  const MatrixXd H0 = random_matrix(2, 9, rng);
  MatrixXd H = H0;
  project_out_basis(H, N);
  EXPECT_LT((H * N).norm(), 1e-12 * H0.norm());
  // Only the part of H along the basis changed: for any v orthogonal to the columns of N, H v = H0 v.
  const MatrixXd P_orth = MatrixXd::Identity(9, 9) - N * (N.transpose() * N).inverse() * N.transpose();
  EXPECT_LT(((H - H0) * P_orth).norm(), 1e-12);
  // A second projection changes nothing; a rank-deficient basis (a zero column) is handled.
  MatrixXd H2 = H;
  project_out_basis(H2, N);
  EXPECT_LT((H2 - H).norm(), 1e-13);
  MatrixXd N_def = N;
  N_def.col(1).setZero();
  MatrixXd H3 = H0;
  project_out_basis(H3, N_def);
  EXPECT_LT((H3 * N_def).norm(), 1e-12 * H0.norm());
  EXPECT_TRUE(H3.allFinite());
}

TEST(StateObservabilityConstraints, ConstrainedPredictionChangesOnlyTheGivenColumns) {
  Rng rng(13);
  State s(with_basis(2));
  MatrixXd U = random_matrix(6, 2, rng);
  const auto r = s.add_block(BlockLayout::euclidean(6), VectorXd::Zero(6), random_spd(6, rng), U);
  const auto l = s.add_block(BlockLayout::euclidean(3), VectorXd::Zero(3), random_spd(3, rng));
  s.cov(*r, *l) = 0.01 * random_matrix(6, 3, rng);
  s.cov(*l, *r) = MatrixXd(s.cov(*r, *l)).transpose();
  const MatrixXd P_rr = s.cov(*r), P_rl = s.cov(*r, *l);
  const MatrixXd F = MatrixXd::Identity(6, 6) + 0.1 * random_matrix(6, 6, rng);
  const MatrixXd Q = 0.01 * random_spd(6, rng);
  const MatrixXd W = U + 0.05 * random_matrix(6, 2, rng);
  s.predict_constrained(*r, F, Q, W, 2, 3);  // columns 2..4 may change
  // The applied transition: F* equals F outside columns 2..4, and F* U = W.
  const MatrixXd U_C = U.middleRows(2, 3);
  MatrixXd Fs = F;
  Fs.middleCols(2, 3) -= (F * U - W) * (U_C.transpose() * U_C).inverse() * U_C.transpose();
  EXPECT_LT((Fs * U - W).norm(), 1e-12);
  EXPECT_EQ(Fs.leftCols(2), F.leftCols(2));
  EXPECT_EQ(Fs.rightCols(1), F.rightCols(1));
  EXPECT_LT((MatrixXd(s.cov(*r)) - (Fs * P_rr * Fs.transpose() + Q)).norm(), 1e-12);
  EXPECT_LT((MatrixXd(s.cov(*r, *l)) - Fs * P_rl).norm(), 1e-12);
  EXPECT_EQ(MatrixXd(s.nullspace(*r)), W);
}

}  // namespace
}  // namespace rtslam::filter

namespace rtslam::filter {
namespace {

// Blocks {4, 3, 7, 3, 5, 3, 7, 2} with a full correlated covariance, then blocks 1, 4 and 6 removed: the remaining
// five blocks lie in three runs of active rows. Returns the dense mirror of the remaining blocks.
DenseMirror fragmented_state(State& s, Rng& rng) {
  DenseMirror d = fill_linear_state(s, {4, 3, 7, 3, 5, 3, 7, 2}, rng);
  for (size_t k : {1, 4, 6}) s.remove_block(d.ids[k]);
  DenseMirror r;
  for (size_t k : {0, 2, 3, 5, 7}) {
    r.ids.push_back(d.ids[k]);
    r.sizes.push_back(d.sizes[k]);
  }
  const int n = r.offset_of(r.ids.size());
  r.x = VectorXd(n);
  r.P = MatrixXd(n, n);
  for (size_t a = 0; a < r.ids.size(); ++a) {
    r.x.segment(r.offset_of(a), r.sizes[a]) = s.mean(r.ids[a]);
    for (size_t b = 0; b < r.ids.size(); ++b)
      r.P.block(r.offset_of(a), r.offset_of(b), r.sizes[a], r.sizes[b]) = s.cov(r.ids[a], r.ids[b]);
  }
  return r;
}

// A measurement of blocks `which` of the mirror: compressed H (rows × Σ sizes) and the dense one.
struct Measurement {
  std::vector<BlockId> blocks;
  MatrixXd Hc, Hf, R;
  VectorXd y;
};

Measurement random_measurement(const DenseMirror& d, const std::vector<size_t>& which, int rows, Rng& rng) {
  Measurement z;
  int cols = 0;
  for (size_t k : which) cols += d.sizes[k];
  z.Hc = random_matrix(rows, cols, rng);
  z.Hf = MatrixXd::Zero(rows, static_cast<int>(d.x.size()));
  int c = 0;
  for (size_t k : which) {
    z.blocks.push_back(d.ids[k]);
    z.Hf.block(0, d.offset_of(k), rows, d.sizes[k]) = z.Hc.middleCols(c, d.sizes[k]);
    c += d.sizes[k];
  }
  z.R = random_spd(rows, rng, 0.05);
  z.y = random_matrix(rows, 1, rng);
  return z;
}

TEST(State, DeferredDowndateIsSeenByInnovationCovarianceAndMeanCorrection) {
  // Corrections leave the downdate outside each block's own covariance pending; the State's own reads in between
  // (innovation covariance, one-point mean correction, the next correction's P Hᵀ) must see the corrected
  // covariance, and applying it must give the closed-form one.
  Rng rng(31);
  State s;
  DenseMirror d = fragmented_state(s, rng);
  for (int step = 0; step < 6; ++step) {
    const Measurement z = random_measurement(d, {static_cast<size_t>(step % 5), static_cast<size_t>((step + 2) % 5)},
                                             2 + step % 3, rng);
    const MatrixXd S_expected = z.Hf * d.P * z.Hf.transpose() + z.R;
    MatrixXd S(z.y.size(), z.y.size());
    s.innovation_covariance(z.blocks, z.Hc, z.R, S);
    EXPECT_LT((S - S_expected).norm(), 1e-10 * S_expected.norm()) << "step " << step;
    VectorXd dx(s.tangent_capacity());
    ASSERT_TRUE(s.mean_correction(z.blocks, z.Hc, z.y, z.R, dx).ok());
    const VectorXd dx_expected = d.P * z.Hf.transpose() * S_expected.ldlt().solve(z.y);
    for (size_t a = 0; a < d.ids.size(); ++a) {
      EXPECT_LT((dx.segment(s.block(d.ids[a]).tangent_offset, d.sizes[a]) -
                 dx_expected.segment(d.offset_of(a), d.sizes[a])).norm(), 1e-10)
          << "step " << step << " block " << a;
    }
    ASSERT_TRUE(s.correct(z.blocks, z.Hc, z.y, z.R).ok());
    d.x += dx_expected;
    d.P -= d.P * z.Hf.transpose() * S_expected.ldlt().solve(z.Hf * d.P);
    EXPECT_GT(s.pending_rows(), 0);
    // Each block's own covariance is current without applying the rest.
    for (size_t a = 0; a < d.ids.size(); ++a) {
      EXPECT_LT((MatrixXd(s.cov(d.ids[a])) - d.P.block(d.offset_of(a), d.offset_of(a), d.sizes[a], d.sizes[a])).norm(),
                1e-10);
    }
  }
  EXPECT_GT(s.pending_rows(), 10);  // nothing above applied the pending downdate
  expect_matches_dense(s, d, 1e-9);
  EXPECT_EQ(s.pending_rows(), 0);
  for (BlockId a : d.ids)
    for (BlockId b : d.ids) EXPECT_EQ(MatrixXd(s.cov(a, b)), MatrixXd(s.cov(b, a)).transpose());
}

TEST(State, ScaleTangentIsDPDWithThePendingDowndateApplied) {
  // A change of units P ← D P D over fragmented blocks, right after a correction whose downdate is still pending.
  Rng rng(33);
  State s;
  DenseMirror d = fragmented_state(s, rng);
  const Measurement z = random_measurement(d, {0, 3}, 3, rng);
  const MatrixXd S = z.Hf * d.P * z.Hf.transpose() + z.R;
  ASSERT_TRUE(s.correct(z.blocks, z.Hc, z.y, z.R).ok());
  d.x += d.P * z.Hf.transpose() * S.ldlt().solve(z.y);
  d.P -= d.P * z.Hf.transpose() * S.ldlt().solve(z.Hf * d.P);
  ASSERT_GT(s.pending_rows(), 0);
  VectorXd factors = VectorXd::Constant(s.tangent_capacity(), 7.0);  // rows of no block: untouched anyway
  VectorXd dense_factors(d.x.size());
  for (size_t a = 0; a < d.ids.size(); ++a) {
    for (int i = 0; i < d.sizes[a]; ++i) {
      const double f = 0.5 + 0.1 * static_cast<double>(a) + 0.01 * i;
      factors[s.block(d.ids[a]).tangent_offset + i] = f;
      dense_factors[d.offset_of(a) + i] = f;
    }
  }
  s.scale_tangent(factors);
  EXPECT_EQ(s.pending_rows(), 0);
  d.P = dense_factors.asDiagonal() * d.P * dense_factors.asDiagonal();
  expect_matches_dense(s, d, 1e-9);  // the means are the caller's: unchanged
  for (BlockId a : d.ids)
    for (BlockId b : d.ids) EXPECT_EQ(MatrixXd(s.cov(a, b)), MatrixXd(s.cov(b, a)).transpose());
}

TEST(State, PendingDowndateBeyondItsCapacityIsAppliedFirst) {
  Rng rng(32);
  State s(StateOptions{.tangent_capacity = 60, .max_measurement_rows = 4});
  DenseMirror d = fragmented_state(s, rng);
  for (int step = 0; step < 7; ++step) {  // 7 × 3 rows > the pending capacity of 8 rows
    const Measurement z = random_measurement(d, {static_cast<size_t>(step % 5)}, 3, rng);
    ASSERT_TRUE(s.correct(z.blocks, z.Hc, z.y, z.R).ok());
    EXPECT_LE(s.pending_rows(), s.pending_capacity());
    const MatrixXd S = z.Hf * d.P * z.Hf.transpose() + z.R;
    d.x += d.P * z.Hf.transpose() * S.ldlt().solve(z.y);
    d.P -= d.P * z.Hf.transpose() * S.ldlt().solve(z.Hf * d.P);
  }
  expect_matches_dense(s, d, 1e-9);
}

TEST(State, GenericAndAvx2KernelsGiveBitIdenticalStatesFmaTheSameUpToRoundingAndAvx512TheFmaOnes) {
  // The kernels' instruction sets perform the same operations in the same order (filter/kernels.hpp).
  auto run = [](KernelIsa isa) {
    set_kernel_isa(isa);
    Rng rng(33);
    State s;
    DenseMirror d = fragmented_state(s, rng);
    for (int step = 0; step < 5; ++step) {
      const Measurement z = random_measurement(d, {0, static_cast<size_t>(1 + step % 4)}, 2 + 2 * step, rng);
      MatrixXd S(z.y.size(), z.y.size());
      s.innovation_covariance(z.blocks, z.Hc, z.R, S);
      EXPECT_TRUE(s.correct(z.blocks, z.Hc, z.y, z.R).ok());
      const MatrixXd F = MatrixXd::Identity(4, 4) + 0.1 * random_matrix(4, 4, rng);
      if (step == 2) s.predict(d.ids[0], F, 0.01 * MatrixXd::Identity(4, 4));
    }
    const MatrixXd P = s.covariance();
    set_kernel_isa(best_kernel_isa());
    return std::make_pair(s.mean_vector(), P);
  };
  const auto generic = run(KernelIsa::generic);
  if (best_kernel_isa() == KernelIsa::generic) GTEST_SKIP() << "no AVX2 on this CPU";
  const auto avx2 = run(KernelIsa::avx2);
  EXPECT_EQ(std::memcmp(generic.first.data(), avx2.first.data(), sizeof(double) * generic.first.size()), 0);
  EXPECT_EQ(std::memcmp(generic.second.data(), avx2.second.data(), sizeof(double) * generic.second.size()), 0);
  // With fused multiply-adds (filter/kernels.hpp): the same state up to rounding.
  if (best_kernel_isa() < KernelIsa::avx2_fma) return;
  const auto fma = run(KernelIsa::avx2_fma);
  EXPECT_LT((fma.first - generic.first).cwiseAbs().maxCoeff(), 1e-12 * generic.first.cwiseAbs().maxCoeff());
  EXPECT_LT((fma.second - generic.second).cwiseAbs().maxCoeff(), 1e-12 * generic.second.cwiseAbs().maxCoeff());
  // AVX-512 downdate tiles: the AVX2 + FMA variant's operations, so its state bit for bit.
  if (best_kernel_isa() < KernelIsa::avx512) return;
  const auto avx512 = run(KernelIsa::avx512);
  EXPECT_EQ(std::memcmp(fma.first.data(), avx512.first.data(), sizeof(double) * fma.first.size()), 0);
  EXPECT_EQ(std::memcmp(fma.second.data(), avx512.second.data(), sizeof(double) * fma.second.size()), 0);
}

}  // namespace
}  // namespace rtslam::filter

namespace rtslam::filter {
namespace {

// Issue 17: slam/state_capacity: 100000 ended in std::bad_alloc (an 80 GB covariance) with no key named.
TEST(StateOptions, ACapacityBeyondTheBoundIsAConfigErrorNamingTheKeyNotABadAlloc) {
  StateOptions o;
  o.tangent_capacity = 100000;
  try {
    State s(o);
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("slam/state_capacity"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("must be in [1, 10000]"), std::string::npos) << e.what();
  }
  o.tangent_capacity = 600;
  EXPECT_NO_THROW(State{o});
}

}  // namespace
}  // namespace rtslam::filter
