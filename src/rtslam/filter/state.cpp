#include "rtslam/filter/state.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/QR>
#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/filter/kernels.hpp"

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
  // The covariance is tangent_capacity² doubles, allocated at once: bound it before std::bad_alloc (or an int
  // overflow of the size) does. 10000 rows take 800 MB.
  if (tangent_capacity > kMaxTangentCapacity || max_measurement_rows > kMaxTangentCapacity ||
      max_block_tangent > kMaxTangentCapacity || ambient_capacity > 2 * kMaxTangentCapacity) {
    throw ConfigError(fmt::format("filter: state capacity of {} covariance rows ({:.1f} GB) must be in [1, {}] "
                                  "(config key slam/state_capacity; measurement rows {}, block {})",
                                  tangent_capacity,
                                  8e-9 * static_cast<double>(tangent_capacity) * static_cast<double>(tangent_capacity),
                                  kMaxTangentCapacity, max_measurement_rows, max_block_tangent));
  }
}

namespace {
// k × k matrices of the observability constraints (k = nullspace_dim <= 16): no heap allocation.
using SmallMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 16, 16>;
int ambient_capacity_of(const StateOptions& o) {
  return o.ambient_capacity > 0 ? o.ambient_capacity : o.tangent_capacity * 4 / 3 + 16;
}
// Measurement rows the pending downdate holds: two full batched corrections.
int pending_capacity_of(const StateOptions& o) { return 2 * o.max_measurement_rows; }
// Non-zero H columns up to which an innovation covariance reads the covariance through the pending downdate; a
// larger one applies it first.
constexpr int kMaxLazyColumns = 64;
}  // namespace

State::State(StateOptions options)
    : options_((options.validate(), options)),
      x_(VectorXd::Zero(ambient_capacity_of(options))),
      P_(MatrixXd::Zero(options.tangent_capacity, options.tangent_capacity)),
      ambient_alloc_(ambient_capacity_of(options)),
      tangent_alloc_(options.tangent_capacity),
      pending_capacity_(pending_capacity_of(options)),
      U_(VectorXd::Zero(kernels::packed_size(options.tangent_capacity, pending_capacity_of(options)))),
      W_(VectorXd::Zero(kernels::packed_size(options.tangent_capacity, options.max_measurement_rows))),
      S_(MatrixXd::Zero(options.max_measurement_rows, options.max_measurement_rows)),
      z_(VectorXd::Zero(options.max_measurement_rows)),
      dx_(VectorXd::Zero(options.tangent_capacity)),
      HP_(MatrixXd::Zero(options.max_measurement_rows, options.tangent_capacity)),
      G_(MatrixXd::Zero(pending_capacity_of(options), options.max_measurement_rows)),
      Gb_(MatrixXd::Zero(pending_capacity_of(options), options.max_measurement_rows)),
      Pnz_(MatrixXd::Zero(kMaxLazyColumns, kMaxLazyColumns)),
      diag_save_(VectorXd::Zero(static_cast<std::int64_t>(options.tangent_capacity) * options.max_block_tangent)),
      tmp_(MatrixXd::Zero(options.max_block_tangent, options.tangent_capacity)),
      tmp_small_(MatrixXd::Zero(options.max_block_tangent, options.max_block_tangent)),
      F_oc_(MatrixXd::Zero(options.max_block_tangent, options.max_block_tangent)) {
  N_ = MatrixXd::Zero(options.tangent_capacity, options.nullspace_dim);
  // Every block has at least one covariance row: with these, adding and removing blocks never allocates.
  blocks_.reserve(static_cast<size_t>(options.tangent_capacity));
  free_ids_.reserve(static_cast<size_t>(options.tangent_capacity));
  runs_.reserve(64);
  spans_.reserve(static_cast<size_t>(options.tangent_capacity));
  active_rows_.reserve(static_cast<size_t>(options.tangent_capacity));
  packed_index_.assign(static_cast<size_t>(options.tangent_capacity), -1);
  groups_.reserve(static_cast<size_t>(2 * (options.tangent_capacity / kernels::kPanelRows + 1)));
  nz_cols_.resize(static_cast<size_t>(options.max_block_tangent));
  predict_rows_.resize(static_cast<size_t>(options.max_block_tangent));
  predict_row_end_.resize(static_cast<size_t>(options.max_block_tangent));
  pht_row_.resize(static_cast<size_t>(options.max_block_tangent));
  nz_hcol_.resize(static_cast<size_t>(options.tangent_capacity));
  nz_prow_.resize(static_cast<size_t>(options.tangent_capacity));
  nz_packed_.resize(static_cast<size_t>(options.tangent_capacity));
  nz_block_.resize(static_cast<size_t>(options.tangent_capacity));
}

void State::reserve(int tangent_capacity) {
  if (tangent_capacity <= options_.tangent_capacity) return;
  RTSLAM_CHECK(used_blocks_ == 0, "State::reserve: the state already holds blocks (grow it before adding any)");
  StateOptions o = options_;
  if (o.ambient_capacity > 0) {
    o.ambient_capacity = static_cast<int>((static_cast<std::int64_t>(o.ambient_capacity) * tangent_capacity +
                                           o.tangent_capacity - 1) / o.tangent_capacity);
  }
  o.tangent_capacity = tangent_capacity;
  *this = State(o);  // validates before anything changes
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
  apply_pending();  // reads the parents' rows and writes the new block's
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
  apply_pending();  // the pending factor is laid out over the active rows, which change
  BlockInfo& b = blocks_[static_cast<size_t>(id)];
  ambient_alloc_.release(b.ambient_offset, b.ambient_size());
  tangent_alloc_.release(b.tangent_offset, b.tangent_size());
  b.used = false;
  free_ids_.push_back(id);
  --used_blocks_;
  rebuild_runs();
}

void State::rebuild_runs() {
  // Member workspaces: adding and removing blocks allocates nothing once they have grown to the block count.
  spans_.clear();
  for (const BlockInfo& b : blocks_)
    if (b.used) spans_.push_back({b.tangent_offset, b.tangent_size()});
  std::sort(spans_.begin(), spans_.end(), [](const Run& a, const Run& c) { return a.begin < c.begin; });
  runs_.clear();
  for (const Run& s : spans_) {
    if (!runs_.empty() && runs_.back().begin + runs_.back().length == s.begin) {
      runs_.back().length += s.length;
    } else {
      runs_.push_back(s);
    }
  }
  std::fill(packed_index_.begin(), packed_index_.end(), -1);
  active_rows_.clear();
  for (const Run& r : runs_) {
    for (int i = r.begin; i < r.begin + r.length; ++i) {
      packed_index_[static_cast<size_t>(i)] = static_cast<int>(active_rows_.size());
      active_rows_.push_back(i);
    }
  }
  // Lane groups of whole panels (kernels.hpp): runs of consecutive covariance rows within each 4 packed rows.
  const int n = static_cast<int>(active_rows_.size());
  const int n_groups = (n + kernels::kPanelRows - 1) / kernels::kPanelRows * (kernels::kPanelRows / kernels::kGroupLanes);
  groups_.clear();
  for (int g = 0; g < n_groups; ++g) {
    kernels::LaneGroup lg;
    for (int l = 0; l < kernels::kGroupLanes; ++l) {
      const int i = g * kernels::kGroupLanes + l;
      if (i >= n) break;
      const int row = active_rows_[static_cast<size_t>(i)];
      if (lg.segments == 0 || active_rows_[static_cast<size_t>(i - 1)] != row - 1) {
        lg.base[lg.segments] = row - l;
        ++lg.segments;
      }
      lg.mask[lg.segments - 1] |= 1u << l;
    }
    groups_.push_back(lg);
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
  apply_pending();
  const BlockInfo& ba = block(a);
  const BlockInfo& bb = block(b);
  return P_.block(ba.tangent_offset, bb.tangent_offset, ba.tangent_size(), bb.tangent_size());
}

Eigen::Block<const MatrixXd> State::cov(BlockId a, BlockId b) const {
  if (a != b) apply_pending();
  const BlockInfo& ba = block(a);
  const BlockInfo& bb = block(b);
  return std::as_const(P_).block(ba.tangent_offset, bb.tangent_offset, ba.tangent_size(), bb.tangent_size());
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
  apply_pending();
  // Cross-covariances P_bo ← F P_bo on every active column outside the block, F taken row by row as its non-zero
  // terms. A row equal to the unit row e_i leaves row i of P_bo (and its mirror) as it is and is skipped: the
  // inertial robot's bias and gravity rows, half of its 18, and a constant-velocity robot's velocity rows. Each
  // element of the others is its row's non-zero terms summed from zero in column order (a term with an exact zero
  // factor would add nothing but the sign of a zero). P_bo's rows are read as the mirror columns P_ob (P is kept
  // exactly symmetric), so that each term is a contiguous vector operation over the part's columns.
  const auto max_terms = static_cast<size_t>(t) * static_cast<size_t>(t);
  if (predict_cols_.size() < max_terms) {  // the first prediction of a block this large (warm-up)
    predict_cols_.resize(max_terms);
    predict_factors_.resize(max_terms);
  }
  int n_rows = 0, n_terms = 0;
  for (int i = 0; i < t; ++i) {
    bool unit = true;
    for (int k = 0; k < t; ++k) unit = unit && F(i, k) == (k == i ? 1.0 : 0.0);
    if (unit) continue;
    predict_rows_[static_cast<size_t>(n_rows)] = i;
    for (int k = 0; k < t; ++k) {
      if (F(i, k) == 0.0) continue;  // (NaN is not zero: it is kept)
      predict_cols_[static_cast<size_t>(n_terms)] = k;
      predict_factors_[static_cast<size_t>(n_terms)] = F(i, k);
      ++n_terms;
    }
    predict_row_end_[static_cast<size_t>(n_rows++)] = n_terms;
  }
  double* const P = P_.data();
  const std::int64_t ld = P_.outerStride();
  for (const Run& r : runs_) {
    const int end = r.begin + r.length;
    const int parts[2][2] = {{r.begin, std::min(end, off)}, {std::max(r.begin, off + t), end}};
    for (const auto& part : parts) {
      const int len = part[1] - part[0];
      if (len <= 0) continue;
      // The new rows, row a at tmp_'s doubles [a len, (a + 1) len) (n_rows len <= t × capacity), before any is
      // written: each reads the old values of the others.
      for (int a = 0, term = 0; a < n_rows; ++a) {
        Eigen::Map<Eigen::VectorXd> row(tmp_.data() + static_cast<std::int64_t>(a) * len, len);
        row.setZero();
        for (const int last = predict_row_end_[static_cast<size_t>(a)]; term < last; ++term) {
          const std::int64_t k = off + predict_cols_[static_cast<size_t>(term)];
          const Eigen::Map<const Eigen::VectorXd> column_k(P + k * ld + part[0], len);  // = row k of P_bo
          row += predict_factors_[static_cast<size_t>(term)] * column_k;
        }
      }
      for (int a = 0; a < n_rows; ++a) {
        const double* row = tmp_.data() + static_cast<std::int64_t>(a) * len;
        const std::int64_t i = off + predict_rows_[static_cast<size_t>(a)];
        std::copy(row, row + len, P + i * ld + part[0]);  // P_ob: column i
        for (int j = 0; j < len; ++j) P[(part[0] + static_cast<std::int64_t>(j)) * ld + i] = row[j];  // P_bo: row i
      }
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

void State::set_nullspace(BlockId b, const Eigen::Ref<const MatrixXd>& N) {
  const BlockInfo& bi = block(b);
  RTSLAM_CHECK(N.rows() == bi.tangent_size() && N.cols() == options_.nullspace_dim,
               "State::set_nullspace: the rows must be tangent size x nullspace_dim");
  N_.block(bi.tangent_offset, 0, bi.tangent_size(), options_.nullspace_dim) = N;
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

namespace {
// The projection of project_out_basis through the Cholesky factor of NᵀN, in plain loops over the small operands
// (A: r × n, N: n × k, r, n <= 64, k <= 16: Eigen's general products and triangular solves cost several times the
// arithmetic at these sizes, and this runs for every predicted observation). False, A untouched, when NᵀN is not
// well conditioned (the squared pivots' ratio below kMinPivotRatio): then (NᵀN)⁻¹ may differ from the
// pseudo-inverse by more than rounding.
bool project_out_basis_cholesky(Eigen::Ref<MatrixXd> A, const Eigen::Ref<const MatrixXd>& N) {
  constexpr double kMinPivotRatio = 1e-6;
  const int r = static_cast<int>(A.rows()), n = static_cast<int>(A.cols()), k = static_cast<int>(N.cols());
  double L[16][16];  // NᵀN, then its Cholesky factor (lower)
  for (int j = 0; j < k; ++j) {
    for (int i = j; i < k; ++i) {
      double acc = 0.0;
      for (int p = 0; p < n; ++p) acc += N(p, i) * N(p, j);
      L[i][j] = acc;
    }
  }
  double lo = std::numeric_limits<double>::infinity(), hi = 0.0;
  for (int j = 0; j < k; ++j) {
    double d = L[j][j];
    for (int l = 0; l < j; ++l) d -= L[j][l] * L[j][l];
    if (!(d > 0.0)) return false;
    lo = std::min(lo, d);
    hi = std::max(hi, d);
    const double djj = std::sqrt(d);
    L[j][j] = djj;
    for (int i = j + 1; i < k; ++i) {
      double v = L[i][j];
      for (int l = 0; l < j; ++l) v -= L[i][l] * L[j][l];
      L[i][j] = v / djj;
    }
  }
  if (!(lo > kMinPivotRatio * hi)) return false;
  // X = (A N)(NᵀN)⁻¹ row by row: y L Lᵀ = a N, forward then backward substitution; then A −= X Nᵀ.
  double X[64][16];
  for (int row = 0; row < r; ++row) {
    double* x = X[row];
    for (int j = 0; j < k; ++j) {
      double acc = 0.0;
      for (int p = 0; p < n; ++p) acc += A(row, p) * N(p, j);
      x[j] = acc;
    }
    for (int j = 0; j < k; ++j) {
      double v = x[j];
      for (int l = 0; l < j; ++l) v -= L[j][l] * x[l];
      x[j] = v / L[j][j];
    }
    for (int j = k - 1; j >= 0; --j) {
      double v = x[j];
      for (int l = j + 1; l < k; ++l) v -= L[l][j] * x[l];
      x[j] = v / L[j][j];
    }
  }
  for (int p = 0; p < n; ++p) {
    for (int row = 0; row < r; ++row) {
      double acc = 0.0;
      for (int j = 0; j < k; ++j) acc += X[row][j] * N(p, j);
      A(row, p) -= acc;
    }
  }
  return true;
}
}  // namespace

void project_out_basis(Eigen::Ref<MatrixXd> A, const Eigen::Ref<const MatrixXd>& N) {
  RTSLAM_CHECK(A.cols() == N.rows() && A.rows() <= 64 && A.cols() <= 64 && N.cols() <= 16,
               "project_out_basis: size mismatch");
  // A full-rank, well-conditioned NᵀN (the usual case) has (NᵀN)⁺ = (NᵀN)⁻¹, applied through its Cholesky factor;
  // the complete orthogonal decomposition's pseudo-inverse handles the rank-deficient and near-singular ones.
  if (project_out_basis_cholesky(A, N)) return;
  const SmallMatrix NtN = N.transpose() * N;
  const Eigen::CompleteOrthogonalDecomposition<SmallMatrix> cod(NtN);
  const SmallMatrix G = cod.pseudoInverse();
  const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 64, 16> AN = A * N;
  A.noalias() -= (AN * G) * N.transpose();
}

void State::compute_PHt(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H) const {
  const int m = static_cast<int>(H.rows());
  const kernels::ActiveRows active = active_rows();
  W_.head(kernels::packed_size(active.n, m)).setZero();
  const kernels::ConstMatrixView P{P_.data(), P_.outerStride()};
  const kernels::ConstMatrixView Hv{H.data(), H.outerStride()};
  // A batched H is block-sparse (each landmark only in its own 2 rows) and a robot's columns are mostly zero (the
  // camera sees its pose only): rows and columns of H that are zero over a block would only add exact zeros, so
  // each block adds its non-zero ones only.
  int col = 0;
  for (BlockId id : blocks) {
    const BlockInfo& b = block(id);
    int k0 = 0, k1 = 0;
    const int nc = nonzero_part(H, col, b.tangent_size(), k0, k1);
    for (int j = 0; j < nc; j += kernels::kMaxPHtColumns) {
      kernels::add_P_Ht(P, active, b.tangent_offset, nz_cols_.data() + j, std::min(kernels::kMaxPHtColumns, nc - j), Hv,
                        col, k0, k1, W_.data(), m);
    }
    col += b.tangent_size();
  }
  if (pending_ > 0) pending_PHt(blocks, H);
}

void State::pending_PHt(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H) const {
  // Off the diagonal blocks the covariance is P_ − U Uᵀ: P Hᵀ = P_ Hᵀ − U G with G = Σ_b U_bᵀ H_bᵀ over the
  // involved blocks b (U_b: U's rows of block b). The rows of an involved block b must not subtract their own
  // share U_b G_b (P_bb is current), so they add it back.
  constexpr int kP = kernels::kPanelRows;
  const int m = static_cast<int>(H.rows());
  const int M = pending_;
  auto G = G_.topLeftCorner(M, m);
  G.setZero();
  int col = 0;
  for (BlockId id : blocks) {
    const BlockInfo& b = block(id);
    const int t = b.tangent_size();
    int k0 = 0, k1 = 0;
    const int nc = nonzero_part(H, col, t, k0, k1);
    if (nc > 0) {
      // G_b = U_bᵀ H_bᵀ on H's non-zero rows [k0, k1) and columns of the block.
      auto Gb = Gb_.block(0, k0, M, k1 - k0);
      Gb.setZero();
      for (int j = 0; j < nc; ++j) {
        const int c = nz_cols_[static_cast<size_t>(j)];
        const double* u = pending_row(packed_index_[static_cast<size_t>(b.tangent_offset + c)]);
        for (int l = k0; l < k1; ++l) {
          const double h = H(l, col + c);
          for (int k = 0; k < M; ++k) Gb(k, l - k0) += u[k * kP] * h;
        }
      }
      G.middleCols(k0, k1 - k0) += Gb;
      // Add back U_b G_b on the block's own rows.
      for (int c = 0; c < t; ++c) {
        const int i = packed_index_[static_cast<size_t>(b.tangent_offset + c)];
        const double* u = pending_row(i);
        double* w = W_.data() + static_cast<std::int64_t>(i / kP) * m * kP + i % kP;
        for (int l = k0; l < k1; ++l) {
          double acc = 0.0;
          for (int k = 0; k < M; ++k) acc += u[k * kP] * Gb(k, l - k0);
          w[l * kP] += acc;
        }
      }
    }
    col += t;
  }
  kernels::subtract_product(W_.data(), static_cast<int>(active_rows_.size()), m, U_.data(), M, pending_capacity_,
                            kernels::ConstMatrixView{G_.data(), G_.outerStride()});
}

int State::nonzero_part(const Eigen::Ref<const MatrixXd>& H, int col, int t, int& k0, int& k1) const {
  const int m = static_cast<int>(H.rows());
  k0 = 0;
  k1 = 0;
  for (int k = 0; k < m; ++k) {
    if (!H.row(k).segment(col, t).isZero(0.0)) {
      if (k1 == 0) k0 = k;
      k1 = k + 1;
    }
  }
  int nc = 0;
  if (k1 > k0) {
    for (int c = 0; c < t; ++c)
      if (!H.col(col + c).segment(k0, k1 - k0).isZero(0.0)) nz_cols_[static_cast<size_t>(nc++)] = c;
  }
  return nc;
}

bool State::factor_S(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H,
                     const Eigen::Ref<const MatrixXd>& R, int m) const {
  constexpr int kP = kernels::kPanelRows;
  auto S = S_.topLeftCorner(m, m);
  S.triangularView<Eigen::Lower>() = R;
  // The lower triangle (all the Cholesky factorization reads): S(k, l) += Σ_c H(k, c) PHt(c, l) over each block's
  // non-zero rows k and columns c.
  int col = 0;
  for (BlockId id : blocks) {
    const BlockInfo& b = block(id);
    int k0 = 0, k1 = 0;
    const int nc = nonzero_part(H, col, b.tangent_size(), k0, k1);
    for (int j = 0; j < nc; ++j) {
      const int i = packed_index_[static_cast<size_t>(b.tangent_offset + nz_cols_[static_cast<size_t>(j)])];
      pht_row_[static_cast<size_t>(j)] = W_.data() + static_cast<std::int64_t>(i / kP) * m * kP + i % kP;
    }
    for (int l = 0; l < m; ++l) {
      for (int k = std::max(k0, l); k < k1; ++k) {
        double acc = 0.0;
        for (int j = 0; j < nc; ++j) acc += H(k, col + nz_cols_[static_cast<size_t>(j)]) * pht_row_[static_cast<size_t>(j)][l * kP];
        S(k, l) += acc;
      }
    }
    col += b.tangent_size();
  }
  // In-place Cholesky on the lower triangle: S_ then holds L.
  Eigen::Ref<MatrixXd> S_ref(S);
  Eigen::LLT<Eigen::Ref<MatrixXd>> llt(S_ref);
  return llt.info() == Eigen::Success;
}

void State::innovation_covariance(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H,
                                  const Eigen::Ref<const MatrixXd>& R, Eigen::Ref<MatrixXd> S) const {
  constexpr int kP = kernels::kPanelRows;
  const int m = static_cast<int>(H.rows());
  RTSLAM_CHECK(m <= options_.max_measurement_rows && H.cols() == total_tangent(blocks) && R.rows() == m &&
                   S.rows() == m && S.cols() == m && H.cols() <= P_.rows(),
               "innovation_covariance: size mismatch");
  // Only the involved blocks' covariance is read, and only where H has a non-zero column (a camera sees the robot's
  // pose, not its velocity or biases): S = H_nz P(nz, nz) H_nzᵀ + R, one triangle, copied onto the other.
  int q = 0;
  int col = 0;
  int bi = 0;
  for (BlockId id : blocks) {
    const BlockInfo& b = block(id);
    for (int c = 0; c < b.tangent_size(); ++c) {
      if (!H.col(col + c).isZero(0.0)) {
        nz_hcol_[static_cast<size_t>(q)] = col + c;
        nz_prow_[static_cast<size_t>(q)] = b.tangent_offset + c;
        nz_packed_[static_cast<size_t>(q)] = packed_index_[static_cast<size_t>(b.tangent_offset + c)];
        nz_block_[static_cast<size_t>(q)] = bi;
        ++q;
      }
    }
    col += b.tangent_size();
    ++bi;
  }
  if (q > kMaxLazyColumns) apply_pending();
  // P(nz, nz), through the pending downdate off the diagonal blocks (lower triangle, mirrored).
  auto Pnz = Pnz_.topLeftCorner(q, q);
  for (int j = 0; j < q; ++j) {
    const double* P_j = P_.data() + static_cast<std::int64_t>(nz_prow_[static_cast<size_t>(j)]) * P_.outerStride();
    for (int i = j; i < q; ++i) {
      double v = P_j[nz_prow_[static_cast<size_t>(i)]];
      if (pending_ > 0 && nz_block_[static_cast<size_t>(i)] != nz_block_[static_cast<size_t>(j)]) {
        const double* ui = pending_row(nz_packed_[static_cast<size_t>(i)]);
        const double* uj = pending_row(nz_packed_[static_cast<size_t>(j)]);
        double acc = 0.0;
        for (int k = 0; k < pending_; ++k) acc += ui[k * kP] * uj[k * kP];
        v -= acc;
      }
      Pnz(i, j) = Pnz(j, i) = v;
    }
  }
  // HP(k, j) = Σ_i H(k, nz_i) P(nz_i, nz_j).
  for (int j = 0; j < q; ++j) {
    for (int k = 0; k < m; ++k) {
      double acc = 0.0;
      for (int i = 0; i < q; ++i) acc += H(k, nz_hcol_[static_cast<size_t>(i)]) * Pnz(i, j);
      HP_(k, j) = acc;
    }
  }
  for (int l = 0; l < m; ++l) {
    for (int k = l; k < m; ++k) {
      double acc = 0.0;
      for (int j = 0; j < q; ++j) acc += HP_(k, j) * H(l, nz_hcol_[static_cast<size_t>(j)]);
      S(k, l) = R(k, l) + acc;
    }
  }
  for (int j = 0; j < m; ++j)
    for (int i = j + 1; i < m; ++i) S(j, i) = S(i, j);
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
  packed_times(m, z, dx);
  return res;
}

void State::packed_times(int m, const Eigen::Ref<const VectorXd>& v, Eigen::Ref<VectorXd> out) const {
  constexpr int kP = kernels::kPanelRows;
  const int n = static_cast<int>(active_rows_.size());
  for (int i = 0; i < n; ++i) {
    const double* w = W_.data() + static_cast<std::int64_t>(i / kP) * m * kP + i % kP;
    double acc = 0.0;
    for (int k = 0; k < m; ++k) acc += w[k * kP] * v[k];
    out[active_rows_[static_cast<size_t>(i)]] = acc;
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
  // W = PHt L⁻ᵀ (in place), active rows only.
  const kernels::ActiveRows active = active_rows();
  kernels::solve_lower_transposed(W_.data(), active.n, m, kernels::ConstMatrixView{S_.data(), S_.outerStride()});
  // Always-on check: every positive variance stays positive (a zero-variance gauge row has W = 0 and stays 0).
  constexpr int kP = kernels::kPanelRows;
  for (int i = 0; i < active.n; ++i) {
    const double* w = W_.data() + static_cast<std::int64_t>(i / kP) * m * kP + i % kP;
    double w2 = 0.0;
    for (int k = 0; k < m; ++k) w2 += w[k * kP] * w[k * kP];
    const int row = active.rows[i];
    const double after = P_(row, row) - w2;
    if (!(after > 0.0 || (after == 0.0 && P_(row, row) == 0.0))) {
      res.status = CorrectionResult::Status::NonPositiveVariance;
      return res;
    }
  }
  // Mean: x ← x ⊕ W z.
  dx_.setZero();
  packed_times(m, z, dx_);
  boxplus_all(x_, dx_, x_);
  // Covariance: P ← P − W Wᵀ, now on the diagonal blocks, deferred elsewhere.
  defer_downdate(m);
  return res;
}

void State::defer_downdate(int m) {
  constexpr int kP = kernels::kPanelRows;
  if (pending_ + m > pending_capacity_) apply_pending();
  // Each block's own covariance, exactly symmetric: P_bb −= W_b W_bᵀ (lower triangle, mirrored).
  double* G = tmp_small_.data();
  const int ldG = static_cast<int>(tmp_small_.outerStride());
  for (const BlockInfo& b : blocks_) {
    if (!b.used) continue;
    const int t = b.tangent_size();
    const int i0 = packed_index_[static_cast<size_t>(b.tangent_offset)];
    kernels::block_gram(W_.data(), m, m, i0, t, G, ldG);
    for (int c = 0; c < t; ++c) {
      for (int r = c; r < t; ++r) {
        const double v = P_(b.tangent_offset + r, b.tangent_offset + c) - G[r + static_cast<std::int64_t>(c) * ldG];
        P_(b.tangent_offset + r, b.tangent_offset + c) = v;
        P_(b.tangent_offset + c, b.tangent_offset + r) = v;
      }
    }
  }
  // W joins the pending factor: columns [pending_, pending_ + m) of U.
  const int np = (static_cast<int>(active_rows_.size()) + kP - 1) / kP;
  for (int p = 0; p < np; ++p) {
    std::copy_n(W_.data() + static_cast<std::int64_t>(p) * m * kP, static_cast<std::int64_t>(m) * kP,
                U_.data() + (static_cast<std::int64_t>(p) * pending_capacity_ + pending_) * kP);
  }
  pending_ += m;
}

void State::scale_tangent(const Eigen::Ref<const VectorXd>& d, const Eigen::Ref<const MatrixXd>& M) {
  RTSLAM_CHECK(d.size() == P_.rows(), "State::scale_tangent: one factor per tangent row of the capacity");
  RTSLAM_CHECK(M.size() == 0 || (M.rows() == N_.cols() && M.cols() == N_.cols()),
               "State::scale_tangent: the basis's change of columns is nullspace_dim square");
  apply_pending();
  constexpr int kMaxBasis = 8;
  RTSLAM_CHECK(N_.cols() <= kMaxBasis, "State::scale_tangent: at most 8 basis columns");
  for (const Run& a : runs_) {
    for (const Run& b : runs_) {
      for (int j = b.begin; j < b.begin + b.length; ++j)
        for (int i = a.begin; i < a.begin + a.length; ++i) P_(i, j) *= d[i] * d[j];
    }
    for (int i = a.begin; i < a.begin + a.length; ++i) {
      double row[kMaxBasis];
      for (Eigen::Index k = 0; k < N_.cols(); ++k) row[k] = d[i] * N_(i, k);
      for (Eigen::Index k = 0; k < N_.cols(); ++k) {
        if (M.size() == 0) {
          N_(i, k) = row[k];
          continue;
        }
        double v = 0.0;
        for (Eigen::Index l = 0; l < N_.cols(); ++l) v += row[l] * M(l, k);
        N_(i, k) = v;
      }
    }
  }
}

void State::apply_pending() const {
  if (pending_ == 0) return;
  // P_ −= U Uᵀ everywhere (one pass, lower triangle mirrored), except on the diagonal blocks, which are current:
  // saved before and restored after.
  std::int64_t o = 0;
  for (const BlockInfo& b : blocks_) {
    if (!b.used) continue;
    const int t = b.tangent_size();
    Eigen::Map<MatrixXd>(diag_save_.data() + o, t, t) = P_.block(b.tangent_offset, b.tangent_offset, t, t);
    o += static_cast<std::int64_t>(t) * t;
  }
  kernels::downdate_mirrored(P_.data(), P_.outerStride(), active_rows(), U_.data(), pending_, pending_capacity_);
  o = 0;
  for (const BlockInfo& b : blocks_) {
    if (!b.used) continue;
    const int t = b.tangent_size();
    P_.block(b.tangent_offset, b.tangent_offset, t, t) = Eigen::Map<const MatrixXd>(diag_save_.data() + o, t, t);
    o += static_cast<std::int64_t>(t) * t;
  }
  pending_ = 0;
}

const MatrixXd& State::covariance() const {
  apply_pending();
  return P_;
}

void State::boxplus_all(const VectorXd& src, const Eigen::Ref<const VectorXd>& dx, VectorXd& out) const {
  if (&out != &src) out = src;
  for (const BlockInfo& b : blocks_) {
    if (!b.used) continue;
    b.layout.boxplus(out.segment(b.ambient_offset, b.ambient_size()), dx.segment(b.tangent_offset, b.tangent_size()));
  }
}

}  // namespace rtslam::filter
