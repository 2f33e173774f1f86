#include "rtslam/filter/state.hpp"

#include <algorithm>

#include <Eigen/QR>
#include <fmt/format.h>

#include "rtslam/core/error.hpp"

namespace rtslam::filter {

const char* to_string(CorrectionResult::Status s) {
  switch (s) {
    case CorrectionResult::Status::Ok: return "ok";
    case CorrectionResult::Status::Gated: return "gated";
    case CorrectionResult::Status::NotPositiveDefinite: return "innovation covariance not positive definite";
    case CorrectionResult::Status::NonPositiveVariance: return "update would make a variance non-positive";
    case CorrectionResult::Status::TooManyRows: return "too many measurement rows";
  }
  return "?";
}

void StateOptions::validate() const {
  if (nullspace_dim < 0 || nullspace_dim > 16 || (nullspace_dim > 0 && max_block_tangent > 64)) {
    throw ConfigError(fmt::format("filter: nullspace_dim = {} must be in [0, 16] (and max_block_tangent = {} <= 64 "
                                  "with it)", nullspace_dim, max_block_tangent));
  }
  if (tangent_capacity <= 0 || max_measurement_rows <= 0 || max_block_tangent <= 0 || ambient_capacity < 0) {
    throw ConfigError(fmt::format("filter: capacities must be positive (tangent {}, rows {}, block {})",
                                  tangent_capacity, max_measurement_rows, max_block_tangent));
  }
}

namespace {
// k × k matrices of the observability constraints (k = nullspace_dim <= 16): no heap allocation.
using SmallMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 16, 16>;
int ambient_capacity_of(const StateOptions& o) {
  return o.ambient_capacity > 0 ? o.ambient_capacity : o.tangent_capacity * 4 / 3 + 16;
}
}  // namespace

State::State(StateOptions options)
    : options_((options.validate(), options)),
      x_(VectorXd::Zero(ambient_capacity_of(options))),
      P_(MatrixXd::Zero(options.tangent_capacity, options.tangent_capacity)),
      ambient_alloc_(ambient_capacity_of(options)),
      tangent_alloc_(options.tangent_capacity),
      PHt_(MatrixXd::Zero(options.tangent_capacity, options.max_measurement_rows)),
      S_(MatrixXd::Zero(options.max_measurement_rows, options.max_measurement_rows)),
      z_(VectorXd::Zero(options.max_measurement_rows)),
      dx_(VectorXd::Zero(options.tangent_capacity)),
      HP_(MatrixXd::Zero(options.max_measurement_rows, options.tangent_capacity)),
      tmp_(MatrixXd::Zero(options.max_block_tangent, options.tangent_capacity)),
      tmp_small_(MatrixXd::Zero(options.max_block_tangent, options.max_block_tangent)),
      F_oc_(MatrixXd::Zero(options.max_block_tangent, options.max_block_tangent)) {
  N_ = MatrixXd::Zero(options.tangent_capacity, options.nullspace_dim);
  blocks_.reserve(256);
  runs_.reserve(64);
}

bool State::can_allocate(const BlockLayout& layout) const {
  return tangent_alloc_.largest_free() >= layout.tangent_size() &&
         ambient_alloc_.largest_free() >= layout.ambient_size();
}

std::optional<BlockId> State::add_block(const BlockLayout& layout, const Eigen::Ref<const VectorXd>& mean,
                                        const Eigen::Ref<const MatrixXd>& cov) {
  const int t = layout.tangent_size();
  RTSLAM_CHECK(mean.size() == layout.ambient_size() && cov.rows() == t && cov.cols() == t,
               fmt::format("block prior sizes: mean {}, cov {}x{} for layout {}", mean.size(), cov.rows(),
                           cov.cols(), layout.describe()));
  const MatrixXd none(t, 0);
  return add_block(layout, mean, {}, none, cov);
}

std::optional<BlockId> State::add_block(const BlockLayout& layout, const Eigen::Ref<const VectorXd>& mean,
                                        const Eigen::Ref<const MatrixXd>& cov,
                                        const Eigen::Ref<const MatrixXd>& nullspace) {
  RTSLAM_CHECK(nullspace.rows() == layout.tangent_size() && nullspace.cols() == options_.nullspace_dim,
               fmt::format("block basis rows: {}x{}, want {}x{}", nullspace.rows(), nullspace.cols(),
                           layout.tangent_size(), options_.nullspace_dim));
  const std::optional<BlockId> id = add_block(layout, mean, cov);
  if (id) N_.middleRows(block(*id).tangent_offset, layout.tangent_size()) = nullspace;
  return id;
}

std::optional<BlockId> State::add_block(const BlockLayout& layout, const Eigen::Ref<const VectorXd>& mean,
                                        std::span<const BlockId> parents,
                                        const Eigen::Ref<const MatrixXd>& J_new_parents,
                                        const Eigen::Ref<const MatrixXd>& Q) {
  const int t = layout.tangent_size();
  const int k = total_tangent(parents);
  RTSLAM_CHECK(t <= options_.max_block_tangent, "block larger than max_block_tangent");
  RTSLAM_CHECK(mean.size() == layout.ambient_size() && J_new_parents.rows() == t && J_new_parents.cols() == k &&
                   Q.rows() == t && Q.cols() == t,
               fmt::format("new block sizes: mean {}, J {}x{} (want {}x{}), Q {}x{}", mean.size(),
                           J_new_parents.rows(), J_new_parents.cols(), t, k, Q.rows(), Q.cols()));
  if (!can_allocate(layout)) return std::nullopt;
  const int aoff = *ambient_alloc_.allocate(layout.ambient_size());
  const int toff = *tangent_alloc_.allocate(t);

  // JP = J P(parents, all active) into tmp_; the new rows are not active yet, so runs_ excludes them.
  for (const Run& r : runs_) {
    auto JP = tmp_.block(0, r.begin, t, r.length);
    JP.setZero();
    int col = 0;
    for (BlockId p : parents) {
      const BlockInfo& bp = block(p);
      JP.noalias() += J_new_parents.middleCols(col, bp.tangent_size()) *
                      P_.block(bp.tangent_offset, r.begin, bp.tangent_size(), r.length);
      col += bp.tangent_size();
    }
  }
  // P_nn = JP(:, parents) Jᵀ + Q.
  auto Pnn = P_.block(toff, toff, t, t);
  Pnn = Q;
  int col = 0;
  for (BlockId p : parents) {
    const BlockInfo& bp = block(p);
    Pnn.noalias() += tmp_.block(0, bp.tangent_offset, t, bp.tangent_size()) *
                     J_new_parents.middleCols(col, bp.tangent_size()).transpose();
    col += bp.tangent_size();
  }
  for (int j = 0; j < t; ++j)
    for (int i = j + 1; i < t; ++i) Pnn(i, j) = Pnn(j, i) = 0.5 * (Pnn(i, j) + Pnn(j, i));
  for (const Run& r : runs_) {
    if (parents.empty()) {
      P_.block(toff, r.begin, t, r.length).setZero();
    } else {
      P_.block(toff, r.begin, t, r.length) = tmp_.block(0, r.begin, t, r.length);
    }
    P_.block(r.begin, toff, r.length, t) = P_.block(toff, r.begin, t, r.length).transpose();
  }

  // The new block's rows of the unobservable basis follow the linearized function: N_new = J N_parents.
  if (options_.nullspace_dim > 0) {
    auto Nn = N_.middleRows(toff, t);
    Nn.setZero();
    int c = 0;
    for (BlockId p : parents) {
      const BlockInfo& bp = block(p);
      Nn.noalias() += J_new_parents.middleCols(c, bp.tangent_size()) * N_.middleRows(bp.tangent_offset, bp.tangent_size());
      c += bp.tangent_size();
    }
  }

  BlockId id;
  if (!free_ids_.empty()) {
    id = free_ids_.back();
    free_ids_.pop_back();
  } else {
    id = static_cast<BlockId>(blocks_.size());
    blocks_.emplace_back();
  }
  BlockInfo& b = blocks_[static_cast<size_t>(id)];
  b.layout = layout;
  b.ambient_offset = aoff;
  b.tangent_offset = toff;
  b.used = true;
  x_.segment(aoff, layout.ambient_size()) = mean;
  ++used_blocks_;
  rebuild_runs();
  return id;
}

void State::remove_block(BlockId id) {
  RTSLAM_CHECK(valid(id), fmt::format("remove_block: {} is not a live block", id));
  BlockInfo& b = blocks_[static_cast<size_t>(id)];
  ambient_alloc_.release(b.ambient_offset, b.ambient_size());
  tangent_alloc_.release(b.tangent_offset, b.tangent_size());
  b.used = false;
  free_ids_.push_back(id);
  --used_blocks_;
  rebuild_runs();
}

void State::rebuild_runs() {
  std::vector<Run> spans;
  spans.reserve(static_cast<size_t>(used_blocks_));
  for (const BlockInfo& b : blocks_)
    if (b.used) spans.push_back({b.tangent_offset, b.tangent_size()});
  std::sort(spans.begin(), spans.end(), [](const Run& a, const Run& c) { return a.begin < c.begin; });
  runs_.clear();
  for (const Run& s : spans) {
    if (!runs_.empty() && runs_.back().begin + runs_.back().length == s.begin) {
      runs_.back().length += s.length;
    } else {
      runs_.push_back(s);
    }
  }
}

Eigen::VectorBlock<VectorXd> State::mean(BlockId id) {
  const BlockInfo& b = block(id);
  return x_.segment(b.ambient_offset, b.ambient_size());
}

Eigen::VectorBlock<const VectorXd> State::mean(BlockId id) const {
  const BlockInfo& b = block(id);
  return x_.segment(b.ambient_offset, b.ambient_size());
}

Eigen::Block<MatrixXd> State::cov(BlockId a, BlockId b) {
  const BlockInfo& ba = block(a);
  const BlockInfo& bb = block(b);
  return P_.block(ba.tangent_offset, bb.tangent_offset, ba.tangent_size(), bb.tangent_size());
}

Eigen::Block<const MatrixXd> State::cov(BlockId a, BlockId b) const {
  const BlockInfo& ba = block(a);
  const BlockInfo& bb = block(b);
  return P_.block(ba.tangent_offset, bb.tangent_offset, ba.tangent_size(), bb.tangent_size());
}

int State::total_tangent(std::span<const BlockId> blocks) const {
  int k = 0;
  for (BlockId b : blocks) {
    RTSLAM_CHECK(valid(b), fmt::format("block {} is not a live block", b));
    k += block(b).tangent_size();
  }
  return k;
}

void State::predict(BlockId id, const Eigen::Ref<const MatrixXd>& F, const Eigen::Ref<const MatrixXd>& Q) {
  const BlockInfo& b = block(id);
  const int t = b.tangent_size();
  const int off = b.tangent_offset;
  RTSLAM_CHECK(F.rows() == t && F.cols() == t && Q.rows() == t && Q.cols() == t, "predict: F/Q size mismatch");
  // Cross-covariances P_bo ← F P_bo on every active column outside the block.
  for (const Run& r : runs_) {
    const int end = r.begin + r.length;
    const int parts[2][2] = {{r.begin, std::min(end, off)}, {std::max(r.begin, off + t), end}};
    for (const auto& part : parts) {
      const int len = part[1] - part[0];
      if (len <= 0) continue;
      auto T = tmp_.block(0, part[0], t, len);
      T.noalias() = F * P_.block(off, part[0], t, len);
      P_.block(off, part[0], t, len) = T;
      P_.block(part[0], off, len, t) = T.transpose();
    }
  }
  // P_bb ← F P_bb Fᵀ + Q (symmetric by construction, then mirrored exactly).
  auto FP = tmp_small_.topLeftCorner(t, t);
  FP.noalias() = F * P_.block(off, off, t, t);
  auto Pbb = P_.block(off, off, t, t);
  Pbb = Q;
  Pbb.noalias() += FP * F.transpose();
  for (int j = 0; j < t; ++j)
    for (int i = j + 1; i < t; ++i) Pbb(j, i) = Pbb(i, j) = 0.5 * (Pbb(i, j) + Pbb(j, i));
}

Eigen::Block<const MatrixXd> State::nullspace(BlockId b) const {
  const BlockInfo& bi = block(b);
  return N_.block(bi.tangent_offset, 0, bi.tangent_size(), options_.nullspace_dim);
}

void State::predict_constrained(BlockId id, const Eigen::Ref<const MatrixXd>& F, const Eigen::Ref<const MatrixXd>& Q,
                                const Eigen::Ref<const MatrixXd>& N_after, int first_col, int n_cols) {
  const int k = options_.nullspace_dim;
  if (k == 0) {
    predict(id, F, Q);
    return;
  }
  const BlockInfo& b = block(id);
  const int t = b.tangent_size();
  RTSLAM_CHECK(N_after.rows() == t && N_after.cols() == k && first_col >= 0 && n_cols >= 1 && first_col + n_cols <= t,
               "predict_constrained: basis or column range mismatch");
  const auto U = N_.block(b.tangent_offset, 0, t, k);
  const auto U_C = U.middleRows(first_col, n_cols);
  auto Fc = F_oc_.topLeftCorner(t, t);
  Fc = F;
  // Fixed maximum sizes (t <= 64, k <= 16): nothing is allocated.
  const SmallMatrix UtU = U_C.transpose() * U_C;
  const Eigen::CompleteOrthogonalDecomposition<SmallMatrix> cod(UtU);
  const SmallMatrix UtU_inv = cod.pseudoInverse();
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 64, 16> residual = F * U;
  residual -= N_after;
  Fc.middleCols(first_col, n_cols).noalias() -= (residual * UtU_inv) * U_C.transpose();
  N_.block(b.tangent_offset, 0, t, k) = N_after;
  predict(id, Fc, Q);
}

void project_out_basis(Eigen::Ref<MatrixXd> A, const Eigen::Ref<const MatrixXd>& N) {
  RTSLAM_CHECK(A.cols() == N.rows() && A.rows() <= 64 && A.cols() <= 64 && N.cols() <= 16,
               "project_out_basis: size mismatch");
  const SmallMatrix NtN = N.transpose() * N;
  const Eigen::CompleteOrthogonalDecomposition<SmallMatrix> cod(NtN);
  const SmallMatrix G = cod.pseudoInverse();
  const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 64, 16> AN = A * N;
  A.noalias() -= (AN * G) * N.transpose();
}

void State::compute_PHt(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H) const {
  const int m = static_cast<int>(H.rows());
  for (const Run& r : runs_) {
    auto rows = PHt_.block(r.begin, 0, r.length, m);
    rows.setZero();
    int col = 0;
    for (BlockId id : blocks) {
      const BlockInfo& b = block(id);
      rows.noalias() +=
          P_.block(r.begin, b.tangent_offset, r.length, b.tangent_size()) * H.middleCols(col, b.tangent_size()).transpose();
      col += b.tangent_size();
    }
  }
}

bool State::factor_S(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H,
                     const Eigen::Ref<const MatrixXd>& R, int m) const {
  auto S = S_.topLeftCorner(m, m);
  S = R;
  int col = 0;
  for (BlockId id : blocks) {
    const BlockInfo& b = block(id);
    S.noalias() += H.middleCols(col, b.tangent_size()) * PHt_.block(b.tangent_offset, 0, b.tangent_size(), m);
    col += b.tangent_size();
  }
  // In-place Cholesky on the lower triangle: S_ then holds L.
  Eigen::Ref<MatrixXd> S_ref(S);
  Eigen::LLT<Eigen::Ref<MatrixXd>> llt(S_ref);
  return llt.info() == Eigen::Success;
}

void State::innovation_covariance(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H,
                                  const Eigen::Ref<const MatrixXd>& R, Eigen::Ref<MatrixXd> S) const {
  const int m = static_cast<int>(H.rows());
  RTSLAM_CHECK(m <= options_.max_measurement_rows && H.cols() == total_tangent(blocks) && R.rows() == m &&
                   S.rows() == m && S.cols() == m,
               "innovation_covariance: size mismatch");
  // Only the involved blocks' covariance is read: S = Σ_a Σ_b H_a P_ab H_bᵀ + R.
  S = R;
  int col_a = 0;
  for (BlockId a : blocks) {
    const BlockInfo& ba = block(a);
    auto HPa = HP_.topRows(m);  // H_a P_a,b for each b, side by side
    int col_b = 0;
    for (BlockId b : blocks) {
      const BlockInfo& bb = block(b);
      HPa.middleCols(col_b, bb.tangent_size()).noalias() =
          H.middleCols(col_a, ba.tangent_size()) *
          P_.block(ba.tangent_offset, bb.tangent_offset, ba.tangent_size(), bb.tangent_size());
      col_b += bb.tangent_size();
    }
    S.noalias() += HPa.leftCols(col_b) * H.transpose();
    col_a += ba.tangent_size();
  }
  for (int j = 0; j < m; ++j)
    for (int i = j + 1; i < m; ++i) S(i, j) = S(j, i) = 0.5 * (S(i, j) + S(j, i));
}

CorrectionResult State::mean_correction(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H,
                                        const Eigen::Ref<const VectorXd>& y, const Eigen::Ref<const MatrixXd>& R,
                                        Eigen::Ref<VectorXd> dx) const {
  const int m = static_cast<int>(H.rows());
  CorrectionResult res;
  if (m > options_.max_measurement_rows) {
    res.status = CorrectionResult::Status::TooManyRows;
    return res;
  }
  RTSLAM_CHECK(H.cols() == total_tangent(blocks) && y.size() == m && R.rows() == m && R.cols() == m &&
                   dx.size() == P_.rows(),
               "mean_correction: size mismatch");
  compute_PHt(blocks, H);
  if (!factor_S(blocks, H, R, m)) {
    res.status = CorrectionResult::Status::NotPositiveDefinite;
    return res;
  }
  const auto L = S_.topLeftCorner(m, m).triangularView<Eigen::Lower>();
  auto z = z_.head(m);
  z = y;
  L.solveInPlace(z);
  res.mahalanobis2 = z.squaredNorm();
  // dx = P Hᵀ S⁻¹ y = PHt L⁻ᵀ z.
  L.transpose().solveInPlace(z);
  dx.setZero();
  for (const Run& r : runs_) dx.segment(r.begin, r.length).noalias() = PHt_.block(r.begin, 0, r.length, m) * z;
  return res;
}

void State::mirror_lower_to_upper(Eigen::Block<MatrixXd> A) {
  // Tiled so that both the read (rows) and the write (columns) stay in cache.
  constexpr int kTile = 32;
  const int n = static_cast<int>(A.rows());
  for (int j0 = 0; j0 < n; j0 += kTile) {
    const int nj = std::min(kTile, n - j0);
    for (int i0 = 0; i0 <= j0; i0 += kTile) {
      const int ni = std::min(kTile, n - i0);
      if (i0 == j0) {
        for (int j = 0; j < nj; ++j)
          for (int i = 0; i < j; ++i) A(i0 + i, j0 + j) = A(j0 + j, i0 + i);
      } else {
        A.block(i0, j0, ni, nj) = A.block(j0, i0, nj, ni).transpose();
      }
    }
  }
}

CorrectionResult State::correct(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H,
                                const Eigen::Ref<const VectorXd>& y, const Eigen::Ref<const MatrixXd>& R,
                                double gate_mahalanobis2) {
  const int m = static_cast<int>(H.rows());
  CorrectionResult res;
  if (m > options_.max_measurement_rows) {
    res.status = CorrectionResult::Status::TooManyRows;
    return res;
  }
  RTSLAM_CHECK(H.cols() == total_tangent(blocks) && y.size() == m && R.rows() == m && R.cols() == m,
               "correct: size mismatch");
  compute_PHt(blocks, H);
  if (!factor_S(blocks, H, R, m)) {
    res.status = CorrectionResult::Status::NotPositiveDefinite;
    return res;
  }
  const auto L = S_.topLeftCorner(m, m).triangularView<Eigen::Lower>();
  auto z = z_.head(m);
  z = y;
  L.solveInPlace(z);
  res.mahalanobis2 = z.squaredNorm();
  if (!(res.mahalanobis2 <= gate_mahalanobis2)) {
    res.status = CorrectionResult::Status::Gated;
    return res;
  }
  // W = PHt L⁻ᵀ (in place in PHt_), active rows only.
  for (const Run& r : runs_) {
    auto W = PHt_.block(r.begin, 0, r.length, m);
    L.transpose().solveInPlace<Eigen::OnTheRight>(W);
  }
  // Always-on check: every positive variance stays positive (a zero-variance gauge row has W = 0 and stays 0).
  for (const Run& r : runs_) {
    for (int i = r.begin; i < r.begin + r.length; ++i) {
      const double after = P_(i, i) - PHt_.row(i).head(m).squaredNorm();
      if (!(after > 0.0 || (after == 0.0 && P_(i, i) == 0.0))) {
        res.status = CorrectionResult::Status::NonPositiveVariance;
        return res;
      }
    }
  }
  // Mean: x ← x ⊕ W z.
  dx_.setZero();
  for (const Run& r : runs_) dx_.segment(r.begin, r.length).noalias() = PHt_.block(r.begin, 0, r.length, m) * z;
  boxplus_all(x_, dx_, x_);
  // Covariance: P ← P − W Wᵀ, lower triangle of each run pair, then mirrored.
  for (size_t a = 0; a < runs_.size(); ++a) {
    const Run ra = runs_[a];
    const auto Wa = PHt_.block(ra.begin, 0, ra.length, m);
    auto Paa = P_.block(ra.begin, ra.begin, ra.length, ra.length);
    Paa.selfadjointView<Eigen::Lower>().rankUpdate(Wa, -1.0);
    mirror_lower_to_upper(Paa);
    for (size_t b = 0; b < a; ++b) {
      const Run rb = runs_[b];
      auto Pab = P_.block(ra.begin, rb.begin, ra.length, rb.length);
      Pab.noalias() -= Wa * PHt_.block(rb.begin, 0, rb.length, m).transpose();
      P_.block(rb.begin, ra.begin, rb.length, ra.length) = Pab.transpose();
    }
  }
  return res;
}

void State::boxplus_all(const VectorXd& src, const Eigen::Ref<const VectorXd>& dx, VectorXd& out) const {
  if (&out != &src) out = src;
  for (const BlockInfo& b : blocks_) {
    if (!b.used) continue;
    b.layout.boxplus(out.segment(b.ambient_offset, b.ambient_size()), dx.segment(b.tangent_offset, b.tangent_size()));
  }
}

}  // namespace rtslam::filter
