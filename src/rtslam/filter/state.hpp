#pragma once
// The EKF engine with sparse indirect indexing (RT-SLAM's "Map" estimation engine).
//
// A State holds the mean vector (ambient coordinates) and the symmetric covariance (tangent coordinates) of a
// set of blocks: robots, sensors, landmarks. Each block owns one contiguous range of the mean and one contiguous
// range of covariance rows, handed out by first-fit allocators; blocks can be added and removed at run time, freed
// ranges are reused, and nothing else moves. Operations touch only what they involve:
//  - predict(b): the rows/columns of block b (P_bb and the cross-covariances P_bo with every active block o);
//  - correct(blocks, H): H is COMPRESSED (columns for the involved blocks only, in the order given); P Hᵀ costs
//    O(n·k) (only where H is non-zero), the covariance downdate O(n²·m) over the active rows only (one triangle,
//    mirrored: exactly symmetric).
// Covariance rows that belong to no block are never read or written. Storage is allocated once at construction:
// predict/correct allocate nothing, however many blocks come and go.
//
// Correction (../shared/MATH.md, "Correction"): S = H P Hᵀ + R = L Lᵀ, W = P Hᵀ L⁻ᵀ, x ← x ⊕ W L⁻¹ y,
// P ← P − W Wᵀ. An always-on check refuses an update that would make any variance non-positive. The orientation
// reset Jacobian I − ½[δθ]× is neglected (it is identity to first order); stated here as MATH.md asks.
//
// Deferred downdate. Outside each block's own covariance P_bb, the downdate P ← P − W Wᵀ is not applied at once:
// correct() updates the mean and every P_bb, and appends W to a pending factor U, so that the covariance is
// P = P_stored − U Uᵀ off the diagonal blocks. The State's own reads (P Hᵀ, innovation covariances) account for U;
// the rank-Σm update of the stored covariance runs in one pass when something needs the stored values: predict,
// add_block, remove_block, the accessors below (except cov(a, a), always current), or U full. The corrections of
// one image then cost one pass over the covariance instead of one each: with ~500 active rows the covariance
// (2 MB) does not stay in cache, and streaming it, not the arithmetic, dominated a small correction. The values are
// those of the immediate downdate up to rounding. The accessors that apply it are const (the covariance they show
// does not change): do not keep a view of an off-diagonal block across a correction, ask for it again.
//
// Observability constraints (optional, `nullspace_dim` > 0; Hesch et al., "Consistency analysis and improvement of
// vision-aided inertial navigation", 2014): the State then tracks, per block, its rows N_b of a basis N of the
// directions the measurements cannot observe (for SLAM: a global translation and rotation of the world). A block
// added as a function of others gets N_new = J N_parents; a robot's prediction may be constrained to map its basis
// at the previous step onto the basis at the new estimate (predict_constrained), and measurement Jacobians are made
// to satisfy H N = 0 (project_out_basis, applied by the caller where the measurement's structure is known). A plain
// EKF linearized at changing estimates would otherwise gain information along N and become overconfident.
//
// Not thread-safe: workspaces are shared by the const queries too.
#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "rtslam/filter/block_layout.hpp"
#include "rtslam/filter/kernels.hpp"
#include "rtslam/filter/range_allocator.hpp"

namespace rtslam::filter {

using Eigen::MatrixXd;
using Eigen::VectorXd;

/// Handle of a block inside one State (stable while the block lives; reused after removal).
using BlockId = int;
constexpr BlockId kNoBlock = -1;

struct StateOptions {
  int tangent_capacity = 600;      // covariance rows (RT-SLAM's MAP_SIZE counts these, "state entries")
  int ambient_capacity = 0;        // mean entries; 0 = tangent_capacity * 4 / 3 + 16
  int max_measurement_rows = 64;   // rows of one batched correction
  int max_block_tangent = 32;      // largest block (robot + calibration states)
  int nullspace_dim = 0;           // columns of the tracked unobservable basis (0: no observability constraints)
  static constexpr int kMaxTangentCapacity = 10000;  // a 10000-row covariance takes 800 MB
  /// Throws ConfigError naming the bound: capacities positive, tangent capacity at most kMaxTangentCapacity.
  void validate() const;
};

struct BlockInfo {
  BlockLayout layout;
  int ambient_offset = 0;
  int tangent_offset = 0;
  bool used = false;
  int ambient_size() const { return layout.ambient_size(); }
  int tangent_size() const { return layout.tangent_size(); }
};

struct CorrectionResult {
  enum class Status { Ok, Gated, NotPositiveDefinite, NonPositiveVariance, TooManyRows };
  Status status = Status::Ok;
  double mahalanobis2 = 0.0;  // yᵀ S⁻¹ y
  bool ok() const { return status == Status::Ok; }
};

const char* to_string(CorrectionResult::Status s);

class State {
 public:
  explicit State(StateOptions options = {});

  // --- blocks ---------------------------------------------------------------------------------------------
  /// Adds a block with an independent prior (zero cross-covariance). nullopt if the state is full.
  std::optional<BlockId> add_block(const BlockLayout& layout, const Eigen::Ref<const VectorXd>& mean,
                                   const Eigen::Ref<const MatrixXd>& cov);
  /// Adds a block that is a function of existing blocks plus independent noise: x_new = g(x_parents, n), with
  /// J_new_parents (t × Σ parents' tangent) and Q = J_new_n N J_new_nᵀ (t × t). Then
  /// P_nn = J P_pp Jᵀ + Q and P_no = J P_po for every active block o (undelayed landmark initialization,
  /// reparametrization). nullopt if the state is full.
  std::optional<BlockId> add_block(const BlockLayout& layout, const Eigen::Ref<const VectorXd>& mean,
                                   std::span<const BlockId> parents, const Eigen::Ref<const MatrixXd>& J_new_parents,
                                   const Eigen::Ref<const MatrixXd>& Q);
  /// Adds a block with an independent prior and its rows of the unobservable basis (nullspace_dim columns).
  std::optional<BlockId> add_block(const BlockLayout& layout, const Eigen::Ref<const VectorXd>& mean,
                                   const Eigen::Ref<const MatrixXd>& cov, const Eigen::Ref<const MatrixXd>& nullspace);
  /// Frees the block's ranges for reuse; every other block is untouched.
  void remove_block(BlockId id);

  bool valid(BlockId id) const { return id >= 0 && id < static_cast<int>(blocks_.size()) && blocks_[id].used; }
  const BlockInfo& block(BlockId id) const { return blocks_[static_cast<size_t>(id)]; }
  int block_count() const { return used_blocks_; }
  /// Tangent rows in use / capacity, and the largest contiguous free range.
  int tangent_used() const { return tangent_alloc_.capacity() - tangent_alloc_.free_total(); }
  int tangent_capacity() const { return tangent_alloc_.capacity(); }
  bool can_allocate(const BlockLayout& layout) const;
  /// Grows the storage to `tangent_capacity` covariance rows (nothing when it has as many), the ambient capacity in
  /// proportion. Only while the state holds no block: storage is allocated before the run, as at construction (a
  /// map that several robots join grows by each one's rows: pipeline/builder.hpp). ConfigError beyond
  /// kMaxTangentCapacity.
  void reserve(int tangent_capacity);

  // --- access ---------------------------------------------------------------------------------------------
  Eigen::VectorBlock<VectorXd> mean(BlockId id);
  Eigen::VectorBlock<const VectorXd> mean(BlockId id) const;
  /// Covariance blocks: the non-const one and the off-diagonal const ones apply the pending downdate first (see
  /// "Deferred downdate"); a block's own covariance cov(a, a) is always current.
  Eigen::Block<MatrixXd> cov(BlockId a, BlockId b);
  Eigen::Block<const MatrixXd> cov(BlockId a, BlockId b) const;
  Eigen::Block<const MatrixXd> cov(BlockId a) const { return cov(a, a); }
  /// The whole mean vector (ambient capacity); unused entries are meaningless.
  const VectorXd& mean_vector() const { return x_; }
  VectorXd& mean_vector() { return x_; }
  /// The whole covariance (tangent capacity), after applying the pending downdate; unused rows are meaningless.
  const MatrixXd& covariance() const;
  /// Applies the pending downdate to the stored covariance (every operation that needs it does so itself).
  void apply_pending() const;
  /// Measurement rows corrected but not yet applied to the stored covariance (at most pending_capacity()).
  int pending_rows() const { return pending_; }
  int pending_capacity() const { return pending_capacity_; }
  /// Active covariance rows as sorted, merged [begin, begin+len) runs.
  struct Run {
    int begin;
    int length;
  };
  std::span<const Run> active_runs() const { return runs_; }

  // --- unobservable basis (nullspace_dim > 0) -------------------------------------------------------------
  int nullspace_dim() const { return options_.nullspace_dim; }
  /// Block b's rows of the basis (tangent size × nullspace_dim).
  Eigen::Block<const MatrixXd> nullspace(BlockId b) const;
  /// Replaces block b's rows of the basis (the blocks moved as a whole: a change of world frame).
  void set_nullspace(BlockId b, const Eigen::Ref<const MatrixXd>& N);

  /// A change of units of the state's tangent coordinates: row i of the covariance (and column i) multiplied by
  /// d(i), i over the tangent capacity (inactive rows untouched), and the unobservable basis re-expressed as
  /// N ← D N M (M: nullspace_dim square, the basis's change of columns; identity when omitted); the caller changes
  /// the means likewise. P ← D P D with D = diag(d). No allocation.
  void scale_tangent(const Eigen::Ref<const VectorXd>& d, const Eigen::Ref<const MatrixXd>& M = MatrixXd());

  // --- prediction -----------------------------------------------------------------------------------------
  /// After the caller has written the predicted mean of block b: P_bb ← F P_bb Fᵀ + Q, P_bo ← F P_bo for every
  /// other active block o. F and Q are (t × t), t the block's tangent size.
  void predict(BlockId b, const Eigen::Ref<const MatrixXd>& F, const Eigen::Ref<const MatrixXd>& Q);
  /// predict() with an observability-constrained transition: with U = N_b (the block's basis rows before) and
  /// W = N_after (the model's basis at the predicted mean), only the columns C = [first_col, first_col + n_cols)
  /// of F change, by the least change that makes F* U = W: F*_C = F_C − (F U − W)(U_Cᵀ U_C)⁺ U_Cᵀ (U_C: rows C of
  /// U). The columns are those the model's linearization point enters (e.g. the attitude error's); the residual
  /// F U − W lies in their range when U_C has full rank. Then N_b ← W. Without a tracked basis this is predict().
  void predict_constrained(BlockId b, const Eigen::Ref<const MatrixXd>& F, const Eigen::Ref<const MatrixXd>& Q,
                           const Eigen::Ref<const MatrixXd>& N_after, int first_col, int n_cols);

  // --- correction -----------------------------------------------------------------------------------------
  /// S = H P Hᵀ + R for a compressed H over `blocks` (m × Σ tangent). Writes S (m × m).
  void innovation_covariance(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H,
                             const Eigen::Ref<const MatrixXd>& R, Eigen::Ref<MatrixXd> S) const;
  /// EKF correction with innovation y = z − h(x). If gate_mahalanobis2 is finite and yᵀS⁻¹y exceeds it, nothing
  /// changes (status Gated). Refuses (changes nothing) when S is not positive definite or a variance would
  /// become non-positive.
  CorrectionResult correct(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H,
                           const Eigen::Ref<const VectorXd>& y, const Eigen::Ref<const MatrixXd>& R,
                           double gate_mahalanobis2 = std::numeric_limits<double>::infinity());
  /// The mean correction dx = P Hᵀ S⁻¹ y alone (tangent capacity; zero on unused rows), without touching the
  /// state: one-point RANSAC hypotheses.
  CorrectionResult mean_correction(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H,
                                   const Eigen::Ref<const VectorXd>& y, const Eigen::Ref<const MatrixXd>& R,
                                   Eigen::Ref<VectorXd> dx) const;
  /// out = src ⊕ dx over every active block (src/out: ambient capacity; dx: tangent capacity). out may be src.
  void boxplus_all(const VectorXd& src, const Eigen::Ref<const VectorXd>& dx, VectorXd& out) const;

 private:
  int total_tangent(std::span<const BlockId> blocks) const;
  /// Packed P Hᵀ (kernels.hpp) of the active rows into W_ (m columns), zero where H has zero rows: each block adds
  /// only the rows of H that are non-zero over its columns (a landmark's 2, the shared blocks' all).
  void compute_PHt(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H) const;
  /// S_ = H PHt(block rows) + R from the packed P Hᵀ; returns false if the Cholesky factorization fails (S_'s lower
  /// triangle then holds L).
  bool factor_S(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H,
                const Eigen::Ref<const MatrixXd>& R, int m) const;
  /// out(row) = W(row, :) v over the active rows of the packed W_ (m columns); other entries untouched.
  void packed_times(int m, const Eigen::Ref<const VectorXd>& v, Eigen::Ref<VectorXd> out) const;
  /// The part of H over one block's columns [col, col + t) that is not zero: rows [k0, k1) (none: k0 == k1) and,
  /// returned, the number of block columns non-zero on those rows, listed (block-relative) in nz_cols_.
  int nonzero_part(const Eigen::Ref<const MatrixXd>& H, int col, int t, int& k0, int& k1) const;
  kernels::ActiveRows active_rows() const {
    return {active_rows_.data(), groups_.data(), static_cast<int>(active_rows_.size())};
  }
  void rebuild_runs();

  /// After a correction with W (packed, m columns): P_bb −= W_b W_bᵀ for every active block b, then W joins U.
  void defer_downdate(int m);
  /// Adds the pending factor's share to the packed P Hᵀ of a correction (see compute_PHt).
  void pending_PHt(std::span<const BlockId> blocks, const Eigen::Ref<const MatrixXd>& H) const;
  /// U(i, k) of the pending factor (packed with panel stride pending_capacity_).
  const double* pending_row(int packed_row) const {
    return U_.data() + (static_cast<std::int64_t>(packed_row / kernels::kPanelRows) * pending_capacity_) *
                           kernels::kPanelRows + packed_row % kernels::kPanelRows;
  }

  StateOptions options_;
  VectorXd x_;
  mutable MatrixXd P_;     // stored covariance: current on the diagonal blocks, P + U Uᵀ elsewhere (apply_pending)
  MatrixXd N_;             // tangent capacity × nullspace_dim: the tracked unobservable basis
  RangeAllocator ambient_alloc_;
  RangeAllocator tangent_alloc_;
  std::vector<BlockInfo> blocks_;
  std::vector<BlockId> free_ids_;
  std::vector<Run> runs_;
  std::vector<int> active_rows_;   // the active covariance rows, increasing (the packed row order)
  std::vector<int> packed_index_;  // tangent capacity: packed row of each covariance row (-1: inactive)
  std::vector<kernels::LaneGroup> groups_;  // the packed rows' lane groups (kernels.hpp)
  int used_blocks_ = 0;

  // The pending downdate: P = P_ − U Uᵀ off the diagonal blocks, U packed (active rows × pending_ columns).
  int pending_capacity_ = 0;
  mutable int pending_ = 0;
  VectorXd U_;

  // Workspaces, sized once.
  std::vector<Run> spans_;  // rebuild_runs
  mutable std::vector<int> nz_cols_;             // max block tangent: nonzero_part
  mutable std::vector<const double*> pht_row_;   // max block tangent: factor_S
  mutable std::vector<int> nz_hcol_, nz_prow_, nz_packed_, nz_block_;  // tangent capacity: innovation_covariance
  mutable VectorXd W_;     // packed (kernels.hpp) active rows × max rows: P Hᵀ, then W = P Hᵀ L⁻ᵀ
  mutable MatrixXd S_;     // max rows × max rows (its lower triangle holds L after factorization)
  mutable VectorXd z_;     // whitened innovation L⁻¹ y
  mutable VectorXd dx_;    // tangent capacity
  mutable MatrixXd HP_;    // max rows × tangent capacity (innovation covariance)
  mutable MatrixXd G_;     // pending capacity × max rows: Uᵀ Hᵀ over a correction's blocks
  mutable MatrixXd Gb_;    // pending capacity × max rows: one block's share of G_
  mutable MatrixXd Pnz_;   // kMaxLazyColumns²: an innovation covariance's P entries
  mutable VectorXd diag_save_;  // the diagonal blocks while the pending downdate is applied
  MatrixXd tmp_;           // max block tangent × tangent capacity (prediction)
  MatrixXd tmp_small_;     // max block tangent × max block tangent
  // predict(): F's rows other than unit rows (their indices, and where each one's terms end) and their non-zero
  // terms (column, factor), in row then column order.
  std::vector<int> predict_rows_, predict_row_end_, predict_cols_;
  std::vector<double> predict_factors_;
  MatrixXd F_oc_;          // max block tangent × max block tangent (constrained transition)
};

/// A ← A (I − N (NᵀN)⁺ Nᵀ): the least change of the rows of A (at most 64 x 64) that makes A N = 0, for a basis N
/// (A.cols() × k, k <= 16; rank-deficient N is handled by the pseudo-inverse). Allocation-free.
void project_out_basis(Eigen::Ref<MatrixXd> A, const Eigen::Ref<const MatrixXd>& N);

}  // namespace rtslam::filter
