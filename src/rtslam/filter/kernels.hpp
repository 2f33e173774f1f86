#pragma once
// Dense kernels of the EKF correction over the active covariance rows (internal to the filter; State uses them).
//
// The correction's tall matrices (P Hᵀ, then the gain factor W = P Hᵀ L⁻ᵀ: n active rows × m measurement rows) live
// in a PACKED layout: the active rows in covariance order, grouped in panels of kPanelRows consecutive rows, each
// panel stored column by column (the kPanelRows values of one column contiguous); rows past n are zero:
//   W(i, k) = packed[(i / kPanelRows * m + k) * kPanelRows + i % kPanelRows].
// A panel is then one or two SIMD registers, whatever holes the active rows have in the covariance; `rows` maps
// packed row i to its covariance row (increasing).
//
// Instruction sets: every kernel has a generic C++ version and, on x86-64, two AVX2 versions compiled with
// __attribute__((target(...))) and chosen at run time (no -march flag: the build runs on any x86-64 CPU). The generic
// and the plain AVX2 versions perform, for every output element, the same sequence of double operations in the same
// order (separate multiply and add), so their results are bit-identical; tests run both and compare. The AVX2 + FMA
// versions (the default where the CPU has FMA: every AVX2 CPU from Intel and AMD) do the same operations in the
// same order with each multiply-add fused, one rounding instead of two: their results differ from the others' in
// the last bits (tests bound the difference), and a run is still deterministic on one machine. Where the CPU has
// AVX-512 (KernelIsa::avx512: Intel Xeon and HEDT CPUs since Skylake-SP/X, Ice/Tiger/Rocket Lake client CPUs, AMD
// Zen 4 and later), the downdate takes 16 rows × 8 columns per tile in 512-bit registers, with the AVX2 + FMA
// variant's operations on every element: the same results, bit for bit (tested); 1.4–1.7 times the AVX2 tiles' speed
// on the project's Intel Xeon host (docs/performance.md), less on CPUs with one 512-bit FMA unit or 256-bit ones
// (Zen 4). The other kernels are the AVX2 + FMA ones.
#include <cstdint>
#include <optional>
#include <string_view>

namespace rtslam::filter {

enum class KernelIsa { generic = 0, avx2 = 1, avx2_fma = 2, avx512 = 3 };

/// The best instruction set this CPU (and build) supports.
KernelIsa best_kernel_isa();
/// The instruction set the kernels use now (process-wide). It starts at best_kernel_isa(), or at the level the
/// environment variable RTSLAM_KERNEL_ISA names (generic, avx2, avx2_fma, avx512; clamped to best_kernel_isa()):
/// `RTSLAM_KERNEL_ISA=generic` gives results that do not depend on the CPU, and a level can be compared with
/// another. A value that names no level is a ConfigError at the first kernel call (a correction, the covariance
/// brought up to date, or set_kernel_isa), and at each one after it.
KernelIsa kernel_isa();
/// The level named (as to_string() writes it), or none.
std::optional<KernelIsa> parse_kernel_isa(std::string_view name);
/// The starting level for the value of RTSLAM_KERNEL_ISA (null or empty: best_kernel_isa()); ConfigError naming the
/// variable when it names no level.
KernelIsa kernel_isa_from_env(const char* value);
/// Selects an instruction set, clamped to best_kernel_isa(); returns the one in use. Tests and benchmarks lower it
/// to exercise the generic path; do not call it while other threads run filter code.
KernelIsa set_kernel_isa(KernelIsa isa);
/// "generic", "avx2", "avx2_fma" or "avx512".
const char* to_string(KernelIsa isa);

namespace kernels {

constexpr int kPanelRows = 8;

/// Doubles of a packed n × m matrix (n rounded up to whole panels).
constexpr std::int64_t packed_size(int n, int m) {
  return static_cast<std::int64_t>((n + kPanelRows - 1) / kPanelRows) * kPanelRows * m;
}

/// Four consecutive packed rows (half a panel) as runs of consecutive covariance rows: segment s holds the lanes
/// of mask[s] (bit l: lane l), and lane l of it is covariance row base[s] + l. Lanes past the active rows are in
/// no segment. Lets the kernels load and store whole registers across holes in the active rows.
struct LaneGroup {
  int segments = 0;
  int base[4] = {0, 0, 0, 0};
  unsigned mask[4] = {0, 0, 0, 0};
};
constexpr int kGroupLanes = 4;

/// The active rows: rows[i] is the covariance row of packed row i (increasing, i < n); groups[g] describes packed
/// rows 4g .. 4g + 3 (whole panels: 2 per panel).
struct ActiveRows {
  const int* rows = nullptr;
  const LaneGroup* groups = nullptr;
  int n = 0;
};

/// Column-major matrix view (element (i, j) at data[i + j * ld]).
struct ConstMatrixView {
  const double* data = nullptr;
  std::int64_t ld = 0;
  double operator()(std::int64_t i, std::int64_t j) const { return data[i + j * ld]; }
};

/// Columns one add_P_Ht call takes.
constexpr int kMaxPHtColumns = 16;

/// W(:, k) += Σ_c P(rows, c0 + c) H(k, h0 + c) over the listed columns c (ncols <= kMaxPHtColumns) for k in
/// [k0, k1), W packed with m columns: one block's share of P Hᵀ, for the rows and columns where H is non-zero. Each
/// element adds the block's sum, accumulated from zero in column order.
void add_P_Ht(ConstMatrixView P, ActiveRows active, int c0, const int* cols, int ncols, ConstMatrixView H, int h0,
              int k0, int k1, double* W, int m);

/// W ← W L⁻ᵀ for packed W (n × m) and the lower-triangular L (m × m): every row solves w Lᵀ = b by forward
/// substitution, w_k = (b_k − Σ_{l<k} w_l L(k, l)) / L(k, k).
void solve_lower_transposed(double* W, int n, int m, ConstMatrixView L);

/// W(:, l) −= Σ_k U(:, k) G(k, l) for l < m, k < mu: W packed with m columns, U packed with panel stride
/// u_stride >= mu columns (U(i, k) at ((i / kPanelRows) * u_stride + k) * kPanelRows + i % kPanelRows), G
/// column-major. Each element subtracts its sum accumulated from zero in k order.
void subtract_product(double* W, int n, int m, const double* U, int mu, int u_stride, ConstMatrixView G);

/// G(r, c) = Σ_k W(i0 + r, k) W(i0 + c, k) for 0 <= c <= r < t (the lower triangle, diagonal included; G column-major
/// with leading dimension ldG, nothing above the diagonal written), W packed with panel stride w_stride >= m: one
/// block's own share of W Wᵀ, its t packed rows consecutive. Every level accumulates each element from zero in k
/// order with a separate multiply and add, so the results are the generic ones, bit for bit, whatever the CPU.
void block_gram(const double* W, int m, int w_stride, int i0, int t, double* G, int ldG);

/// P ← P − W Wᵀ over the active rows (P column-major, leading dimension ldP) for W packed with panel stride
/// w_stride >= m: the lower triangle (diagonal included) is updated, each element minus Σ_k W(i, k) W(j, k)
/// accumulated from zero in k order, and each updated value is copied onto its mirror above the diagonal, so P
/// stays exactly symmetric. Rows and columns of P outside the active rows are neither read nor written.
void downdate_mirrored(double* P, std::int64_t ldP, ActiveRows active, const double* W, int m, int w_stride);

}  // namespace kernels
}  // namespace rtslam::filter
