#include "rtslam/filter/kernels.hpp"

#include <algorithm>
#include <atomic>

#if defined(__x86_64__)
#include <immintrin.h>
#define RTSLAM_FILTER_AVX2 __attribute__((target("avx2")))  // the helpers below (no arithmetic)
#endif

namespace rtslam::filter {

namespace {

KernelIsa detect() {
#if defined(__x86_64__)
  // __builtin_cpu_supports also checks that the OS saves the AVX registers.
  __builtin_cpu_init();
  if (!__builtin_cpu_supports("avx2")) return KernelIsa::generic;
  return __builtin_cpu_supports("fma") ? KernelIsa::avx2_fma : KernelIsa::avx2;
#else
  return KernelIsa::generic;
#endif
}

std::atomic<KernelIsa>& current() {
  static std::atomic<KernelIsa> isa{best_kernel_isa()};
  return isa;
}

}  // namespace

KernelIsa best_kernel_isa() {
  static const KernelIsa best = detect();
  return best;
}

KernelIsa kernel_isa() { return current().load(std::memory_order_relaxed); }

KernelIsa set_kernel_isa(KernelIsa isa) {
  const KernelIsa used = static_cast<int>(isa) < static_cast<int>(best_kernel_isa()) ? isa : best_kernel_isa();
  current().store(used, std::memory_order_relaxed);
  return used;
}

const char* to_string(KernelIsa isa) {
  switch (isa) {
    case KernelIsa::generic: return "generic";
    case KernelIsa::avx2: return "avx2";
    case KernelIsa::avx2_fma:
      return "avx2_fma";
  }
  return "unknown";
}

namespace kernels {

namespace {

constexpr int kP = kPanelRows;
constexpr int kTileCols = 4;  // columns of one downdate tile (kP rows × 4 columns: 8 AVX2 accumulators)
static_assert(kP == 2 * kGroupLanes && kTileCols == kGroupLanes);

int panel_count(int n) { return (n + kP - 1) / kP; }

// Generic versions: plain loops over a panel's lanes (the compiler vectorizes them with the baseline SSE2). The
// AVX2 versions further down perform the same operations on every element in the same order.

void add_P_Ht_body(ConstMatrixView P, ActiveRows active, int c0, const int* cols,
                                                 int ncols, ConstMatrixView H, int h0, int k0, int k1, double* W,
                                                 int m) {
  const int np = panel_count(active.n);
  for (int p = 0; p < np; ++p) {
    const int i0 = p * kP;
    const int cnt = std::min(kP, active.n - i0);
    const int* rows = active.rows + i0;
    // The panel's rows of the listed columns, gathered once (rows past n: zero).
    double x[kMaxPHtColumns][kP];
    if (cnt == kP && rows[kP - 1] - rows[0] == kP - 1) {
      for (int j = 0; j < ncols; ++j) {
        const double* src = P.data + (c0 + cols[j]) * P.ld + rows[0];
        for (int r = 0; r < kP; ++r) x[j][r] = src[r];
      }
    } else {
      for (int j = 0; j < ncols; ++j) {
        const double* col = P.data + (c0 + cols[j]) * P.ld;
        for (int r = 0; r < kP; ++r) x[j][r] = r < cnt ? col[rows[r]] : 0.0;
      }
    }
    for (int k = k0; k < k1; ++k) {
      double acc[kP] = {};
      for (int j = 0; j < ncols; ++j) {
        const double h = H(k, h0 + cols[j]);
        for (int r = 0; r < kP; ++r) acc[r] += x[j][r] * h;
      }
      double* w = W + (static_cast<std::int64_t>(p) * m + k) * kP;
      for (int r = 0; r < kP; ++r) w[r] += acc[r];
    }
  }
}

void solve_body(double* W, int n, int m, ConstMatrixView L) {
  // Blocks of 4 columns: the 4 × kP values being solved stay in registers while the finished columns l < k0 are
  // subtracted. Every element still subtracts w_l L(k, l) in l order, then divides.
  constexpr int kB = 4;
  const int np = panel_count(n);
  for (int p = 0; p < np; ++p) {
    double* w = W + static_cast<std::int64_t>(p) * m * kP;
    int k0 = 0;
    for (; k0 + kB <= m; k0 += kB) {
      double v[kB][kP];
      for (int c = 0; c < kB; ++c)
        for (int r = 0; r < kP; ++r) v[c][r] = w[(k0 + c) * kP + r];
      for (int l = 0; l < k0; ++l) {
        const double* x = w + l * kP;
        for (int c = 0; c < kB; ++c) {
          const double a = L(k0 + c, l);
          for (int r = 0; r < kP; ++r) v[c][r] -= x[r] * a;
        }
      }
      for (int c = 0; c < kB; ++c) {
        for (int l = k0; l < k0 + c; ++l) {
          const double a = L(k0 + c, l);
          for (int r = 0; r < kP; ++r) v[c][r] -= w[l * kP + r] * a;
        }
        const double d = L(k0 + c, k0 + c);
        for (int r = 0; r < kP; ++r) w[(k0 + c) * kP + r] = v[c][r] / d;
      }
    }
    for (int k = k0; k < m; ++k) {
      double v[kP];
      for (int r = 0; r < kP; ++r) v[r] = w[k * kP + r];
      for (int l = 0; l < k; ++l) {
        const double a = L(k, l);
        for (int r = 0; r < kP; ++r) v[r] -= w[l * kP + r] * a;
      }
      const double d = L(k, k);
      for (int r = 0; r < kP; ++r) w[k * kP + r] = v[r] / d;
    }
  }
}

void subtract_product_body(double* W, int n, int m, const double* U, int mu,
                                                         int u_stride, ConstMatrixView G) {
  const int np = panel_count(n);
  for (int p = 0; p < np; ++p) {
    const double* u = U + static_cast<std::int64_t>(p) * u_stride * kP;
    double* w = W + static_cast<std::int64_t>(p) * m * kP;
    for (int l = 0; l < m; ++l) {
      double acc[kP] = {};
      for (int k = 0; k < mu; ++k) {
        const double g = G(k, l);
        for (int r = 0; r < kP; ++r) acc[r] += u[k * kP + r] * g;
      }
      for (int r = 0; r < kP; ++r) w[l * kP + r] -= acc[r];
    }
  }
}

// acc[c][r] = Σ_k W(i0 + r, k) W(j0 + c, k), from zero in k order; wi: panel of i0, wj: W(j0, 0) in its panel.
void tile_sum(const double* wi, const double* wj, int m, double acc[kTileCols][kP]) {
  for (int c = 0; c < kTileCols; ++c)
    for (int r = 0; r < kP; ++r) acc[c][r] = 0.0;
  for (int k = 0; k < m; ++k) {
    const double* a = wi + k * kP;
    const double* b = wj + k * kP;
    for (int c = 0; c < kTileCols; ++c)
      for (int r = 0; r < kP; ++r) acc[c][r] += a[r] * b[c];
  }
}

// Writes one tile element by element: the lower-triangle elements (i >= j) of rows i0.., columns j0.. get
// P − acc, mirrored above the diagonal.
void write_tile(double* P, std::int64_t ldP, ActiveRows active, int i0, int j0, const double acc[kTileCols][kP]) {
  for (int c = 0; c < kTileCols; ++c) {
    const int j = j0 + c;
    if (j >= active.n) break;
    const std::int64_t pj = active.rows[j];
    double* col_j = P + pj * ldP;
    for (int r = 0; r < kP; ++r) {
      const int i = i0 + r;
      if (i >= active.n) break;
      if (i < j) continue;
      const std::int64_t pi = active.rows[i];
      const double v = col_j[pi] - acc[c][r];
      col_j[pi] = v;
      if (i != j) P[pj + pi * ldP] = v;
    }
  }
}

void add_P_Ht_generic(ConstMatrixView P, ActiveRows active, int c0, const int* cols, int ncols, ConstMatrixView H,
                      int h0, int k0, int k1, double* W, int m) {
  add_P_Ht_body(P, active, c0, cols, ncols, H, h0, k0, k1, W, m);
}

void solve_generic(double* W, int n, int m, ConstMatrixView L) { solve_body(W, n, m, L); }

void subtract_product_generic(double* W, int n, int m, const double* U, int mu, int u_stride, ConstMatrixView G) {
  subtract_product_body(W, n, m, U, mu, u_stride, G);
}

void downdate_generic(double* P, std::int64_t ldP, ActiveRows active, const double* W, int m, int w_stride) {
  const int np = panel_count(active.n);
  for (int j0 = 0; j0 < active.n; j0 += kTileCols) {
    const double* wj = W + static_cast<std::int64_t>(j0 / kP) * w_stride * kP + j0 % kP;
    for (int p = j0 / kP; p < np; ++p) {
      double acc[kTileCols][kP];
      tile_sum(W + static_cast<std::int64_t>(p) * w_stride * kP, wj, m, acc);
      write_tile(P, ldP, active, p * kP, j0, acc);
    }
  }
}

#if defined(__x86_64__)

// Lane masks for maskload/maskstore: entry b has lane l set when bit l of b is.
alignas(32) constexpr std::int64_t kLaneMasks[16][4] = {
    {0, 0, 0, 0},   {-1, 0, 0, 0},   {0, -1, 0, 0},   {-1, -1, 0, 0},   {0, 0, -1, 0},   {-1, 0, -1, 0},
    {0, -1, -1, 0}, {-1, -1, -1, 0}, {0, 0, 0, -1},   {-1, 0, 0, -1},   {0, -1, 0, -1},  {-1, -1, 0, -1},
    {0, 0, -1, -1}, {-1, 0, -1, -1}, {0, -1, -1, -1}, {-1, -1, -1, -1}};

RTSLAM_FILTER_AVX2 inline __m256i lane_mask(unsigned bits) {
  return _mm256_load_si256(reinterpret_cast<const __m256i*>(kLaneMasks[bits]));
}

// The 4 values of group g at P + offset + row(lane): one load when the group is one full segment, else one masked
// load per segment, blended (exact: no arithmetic on the loaded values).
RTSLAM_FILTER_AVX2 inline __m256d load_group(const double* P, const LaneGroup& g) {
  if (g.segments == 1 && g.mask[0] == 0xF) return _mm256_loadu_pd(P + g.base[0]);
  __m256d v = _mm256_setzero_pd();
  for (int s = 0; s < g.segments; ++s) {
    const __m256i mk = lane_mask(g.mask[s]);
    v = _mm256_blendv_pd(v, _mm256_maskload_pd(P + g.base[s], mk), _mm256_castsi256_pd(mk));
  }
  return v;
}

RTSLAM_FILTER_AVX2 inline void store_group(double* P, const LaneGroup& g, __m256d v) {
  if (g.segments == 1 && g.mask[0] == 0xF) {
    _mm256_storeu_pd(P + g.base[0], v);
    return;
  }
  for (int s = 0; s < g.segments; ++s) _mm256_maskstore_pd(P + g.base[s], lane_mask(g.mask[s]), v);
}

RTSLAM_FILTER_AVX2 inline bool full_group(const LaneGroup& g) { return g.segments == 1 && g.mask[0] == 0xF; }

// Stores the transpose of the 4 × 4 block [c0 c1 c2 c3] (columns) as 4 rows of 4 at dst, dst + ld, ...
RTSLAM_FILTER_AVX2 inline void transpose_store(double* dst, std::int64_t ld, __m256d c0, __m256d c1, __m256d c2,
                                               __m256d c3) {
  const __m256d t0 = _mm256_unpacklo_pd(c0, c1), t1 = _mm256_unpackhi_pd(c0, c1);
  const __m256d t2 = _mm256_unpacklo_pd(c2, c3), t3 = _mm256_unpackhi_pd(c2, c3);
  _mm256_storeu_pd(dst, _mm256_permute2f128_pd(t0, t2, 0x20));
  _mm256_storeu_pd(dst + ld, _mm256_permute2f128_pd(t1, t3, 0x20));
  _mm256_storeu_pd(dst + 2 * ld, _mm256_permute2f128_pd(t0, t2, 0x31));
  _mm256_storeu_pd(dst + 3 * ld, _mm256_permute2f128_pd(t1, t3, 0x31));
}

// The columns j0 .. j0 + 3 of the downdate (kTileCols), as every tile of theirs needs them.
struct TileColumns {
  int j0 = 0;
  const double* wj = nullptr;     // W(j0, 0) in the packed layout
  const LaneGroup* gc = nullptr;  // their lane group
  bool contiguous = false;        // four consecutive covariance rows
  std::int64_t col_row[kTileCols] = {0, 0, 0, 0};  // covariance rows (lanes past n repeat j0's: never written)
};

// The AVX2 kernels in two variants (kernels_avx2.inc): avx2:: with separate multiplies and adds, the generic
// versions' results bit for bit; avx2_fma:: with fused multiply-adds. The FMA variant gets its own target so that
// the plain one has no FMA to fuse with, and the module is compiled with -ffp-contract=off (filter/CMakeLists.txt)
// so that a -march build does not fuse the plain and generic versions either.
#define RTSLAM_KERNEL_NS avx2
#define RTSLAM_KERNEL_TARGET __attribute__((target("avx2")))
#define RTSLAM_MADD(c, a, b) _mm256_add_pd(c, _mm256_mul_pd(a, b))
#define RTSLAM_NMSUB(c, a, b) _mm256_sub_pd(c, _mm256_mul_pd(a, b))
#include "kernels_avx2.inc"
#undef RTSLAM_KERNEL_NS
#undef RTSLAM_KERNEL_TARGET
#undef RTSLAM_MADD
#undef RTSLAM_NMSUB

#define RTSLAM_KERNEL_NS avx2_fma
#define RTSLAM_KERNEL_TARGET __attribute__((target("avx2,fma")))
#define RTSLAM_MADD(c, a, b) _mm256_fmadd_pd(a, b, c)
#define RTSLAM_NMSUB(c, a, b) _mm256_fnmadd_pd(a, b, c)
#include "kernels_avx2.inc"
#undef RTSLAM_KERNEL_NS
#undef RTSLAM_KERNEL_TARGET
#undef RTSLAM_MADD
#undef RTSLAM_NMSUB
#undef RTSLAM_FILTER_AVX2

#endif  // __x86_64__

}  // namespace

void add_P_Ht(ConstMatrixView P, ActiveRows active, int c0, const int* cols, int ncols, ConstMatrixView H, int h0,
              int k0, int k1, double* W, int m) {
#if defined(__x86_64__)
  switch (kernel_isa()) {
    case KernelIsa::avx2_fma:
      return avx2_fma::add_P_Ht_avx2(P, active, c0, cols, ncols, H, h0, k0, k1, W, m);
    case KernelIsa::avx2:
      return avx2::add_P_Ht_avx2(P, active, c0, cols, ncols, H, h0, k0, k1, W, m);
    case KernelIsa::generic:
      break;
  }
#endif
  add_P_Ht_generic(P, active, c0, cols, ncols, H, h0, k0, k1, W, m);
}

void solve_lower_transposed(double* W, int n, int m, ConstMatrixView L) {
#if defined(__x86_64__)
  switch (kernel_isa()) {
    case KernelIsa::avx2_fma:
      return avx2_fma::solve_avx2(W, n, m, L);
    case KernelIsa::avx2:
      return avx2::solve_avx2(W, n, m, L);
    case KernelIsa::generic:
      break;
  }
#endif
  solve_generic(W, n, m, L);
}

void subtract_product(double* W, int n, int m, const double* U, int mu, int u_stride, ConstMatrixView G) {
#if defined(__x86_64__)
  switch (kernel_isa()) {
    case KernelIsa::avx2_fma:
      return avx2_fma::subtract_product_avx2(W, n, m, U, mu, u_stride, G);
    case KernelIsa::avx2:
      return avx2::subtract_product_avx2(W, n, m, U, mu, u_stride, G);
    case KernelIsa::generic:
      break;
  }
#endif
  subtract_product_generic(W, n, m, U, mu, u_stride, G);
}

void downdate_mirrored(double* P, std::int64_t ldP, ActiveRows active, const double* W, int m, int w_stride) {
#if defined(__x86_64__)
  switch (kernel_isa()) {
    case KernelIsa::avx2_fma:
      return avx2_fma::downdate_avx2(P, ldP, active, W, m, w_stride);
    case KernelIsa::avx2:
      return avx2::downdate_avx2(P, ldP, active, W, m, w_stride);
    case KernelIsa::generic:
      break;
  }
#endif
  downdate_generic(P, ldP, active, W, m, w_stride);
}

}  // namespace kernels
}  // namespace rtslam::filter
