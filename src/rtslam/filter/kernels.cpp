#include "rtslam/filter/kernels.hpp"

#include <algorithm>
#include <atomic>

#if defined(__x86_64__)
#include <immintrin.h>
#define RTSLAM_FILTER_AVX2 __attribute__((target("avx2")))
#endif

namespace rtslam::filter {

namespace {

KernelIsa detect() {
#if defined(__x86_64__)
  // __builtin_cpu_supports also checks that the OS saves the AVX registers.
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") ? KernelIsa::avx2 : KernelIsa::generic;
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

// The AVX2 versions below do the generic bodies' operations in the same order, a panel's 8 rows in two registers.

RTSLAM_FILTER_AVX2 void add_P_Ht_avx2(ConstMatrixView P, ActiveRows active, int c0, const int* cols, int ncols,
                                      ConstMatrixView H, int h0, int k0, int k1, double* W, int m) {
  const int np = panel_count(active.n);
  for (int p = 0; p < np; ++p) {
    const int i0 = p * kP;
    const int cnt = std::min(kP, active.n - i0);
    const int* rows = active.rows + i0;
    alignas(32) double x[kMaxPHtColumns][kP];
    if (cnt == kP && rows[kP - 1] - rows[0] == kP - 1) {
      for (int j = 0; j < ncols; ++j) {
        const double* src = P.data + (c0 + cols[j]) * P.ld + rows[0];
        _mm256_store_pd(x[j], _mm256_loadu_pd(src));
        _mm256_store_pd(x[j] + 4, _mm256_loadu_pd(src + 4));
      }
    } else {
      for (int j = 0; j < ncols; ++j) {
        const double* col = P.data + (c0 + cols[j]) * P.ld;
        for (int r = 0; r < kP; ++r) x[j][r] = r < cnt ? col[rows[r]] : 0.0;
      }
    }
    for (int k = k0; k < k1; ++k) {
      __m256d lo = _mm256_setzero_pd(), hi = _mm256_setzero_pd();
      for (int j = 0; j < ncols; ++j) {
        const __m256d h = _mm256_set1_pd(H(k, h0 + cols[j]));
        lo = _mm256_add_pd(lo, _mm256_mul_pd(_mm256_load_pd(x[j]), h));
        hi = _mm256_add_pd(hi, _mm256_mul_pd(_mm256_load_pd(x[j] + 4), h));
      }
      double* w = W + (static_cast<std::int64_t>(p) * m + k) * kP;
      _mm256_storeu_pd(w, _mm256_add_pd(_mm256_loadu_pd(w), lo));
      _mm256_storeu_pd(w + 4, _mm256_add_pd(_mm256_loadu_pd(w + 4), hi));
    }
  }
  _mm256_zeroupper();  // before plain SSE code (vision/simd.hpp)
}

RTSLAM_FILTER_AVX2 void solve_avx2(double* W, int n, int m, ConstMatrixView L) {
  constexpr int kB = 4;
  const int np = panel_count(n);
  for (int p = 0; p < np; ++p) {
    double* w = W + static_cast<std::int64_t>(p) * m * kP;
    int k0 = 0;
    for (; k0 + kB <= m; k0 += kB) {
      __m256d v[kB][2];
      for (int c = 0; c < kB; ++c) {
        v[c][0] = _mm256_loadu_pd(w + (k0 + c) * kP);
        v[c][1] = _mm256_loadu_pd(w + (k0 + c) * kP + 4);
      }
      for (int l = 0; l < k0; ++l) {
        const __m256d xl = _mm256_loadu_pd(w + l * kP), xh = _mm256_loadu_pd(w + l * kP + 4);
        for (int c = 0; c < kB; ++c) {
          const __m256d a = _mm256_set1_pd(L(k0 + c, l));
          v[c][0] = _mm256_sub_pd(v[c][0], _mm256_mul_pd(xl, a));
          v[c][1] = _mm256_sub_pd(v[c][1], _mm256_mul_pd(xh, a));
        }
      }
      for (int c = 0; c < kB; ++c) {
        for (int l = k0; l < k0 + c; ++l) {
          const __m256d a = _mm256_set1_pd(L(k0 + c, l));
          v[c][0] = _mm256_sub_pd(v[c][0], _mm256_mul_pd(_mm256_loadu_pd(w + l * kP), a));
          v[c][1] = _mm256_sub_pd(v[c][1], _mm256_mul_pd(_mm256_loadu_pd(w + l * kP + 4), a));
        }
        const __m256d d = _mm256_set1_pd(L(k0 + c, k0 + c));
        _mm256_storeu_pd(w + (k0 + c) * kP, _mm256_div_pd(v[c][0], d));
        _mm256_storeu_pd(w + (k0 + c) * kP + 4, _mm256_div_pd(v[c][1], d));
      }
    }
    for (int k = k0; k < m; ++k) {
      __m256d vl = _mm256_loadu_pd(w + k * kP), vh = _mm256_loadu_pd(w + k * kP + 4);
      for (int l = 0; l < k; ++l) {
        const __m256d a = _mm256_set1_pd(L(k, l));
        vl = _mm256_sub_pd(vl, _mm256_mul_pd(_mm256_loadu_pd(w + l * kP), a));
        vh = _mm256_sub_pd(vh, _mm256_mul_pd(_mm256_loadu_pd(w + l * kP + 4), a));
      }
      const __m256d d = _mm256_set1_pd(L(k, k));
      _mm256_storeu_pd(w + k * kP, _mm256_div_pd(vl, d));
      _mm256_storeu_pd(w + k * kP + 4, _mm256_div_pd(vh, d));
    }
  }
  _mm256_zeroupper();
}

RTSLAM_FILTER_AVX2 void subtract_product_avx2(double* W, int n, int m, const double* U, int mu, int u_stride,
                                              ConstMatrixView G) {
  const int np = panel_count(n);
  for (int p = 0; p < np; ++p) {
    const double* u = U + static_cast<std::int64_t>(p) * u_stride * kP;
    double* w = W + static_cast<std::int64_t>(p) * m * kP;
    for (int l = 0; l < m; ++l) {
      __m256d lo = _mm256_setzero_pd(), hi = _mm256_setzero_pd();
      for (int k = 0; k < mu; ++k) {
        const __m256d g = _mm256_set1_pd(G(k, l));
        lo = _mm256_add_pd(lo, _mm256_mul_pd(_mm256_loadu_pd(u + k * kP), g));
        hi = _mm256_add_pd(hi, _mm256_mul_pd(_mm256_loadu_pd(u + k * kP + 4), g));
      }
      _mm256_storeu_pd(w + l * kP, _mm256_sub_pd(_mm256_loadu_pd(w + l * kP), lo));
      _mm256_storeu_pd(w + l * kP + 4, _mm256_sub_pd(_mm256_loadu_pd(w + l * kP + 4), hi));
    }
  }
  _mm256_zeroupper();
}

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

// One tile of the downdate: packed rows p * kP .. + 7 against the columns tc (p >= tc.j0 / kP).
RTSLAM_FILTER_AVX2 inline void downdate_tile(double* P, std::int64_t ldP, ActiveRows active, const double* W, int m,
                                             int w_stride, const TileColumns& tc, int p) {
  const int n = active.n;
  const int* rows = active.rows;
  const int j0 = tc.j0;
  const double* wj = tc.wj;
  const LaneGroup& gc = *tc.gc;
  const bool cols_contiguous = tc.contiguous;
  const std::int64_t* col_row = tc.col_row;
  const int i0 = p * kP;
  const double* wi = W + static_cast<std::int64_t>(p) * w_stride * kP;
  // Same sums as tile_sum: acc_c = acc_c + a * b_c, lanes = rows.
  __m256d a0l = _mm256_setzero_pd(), a0h = _mm256_setzero_pd(), a1l = _mm256_setzero_pd(),
          a1h = _mm256_setzero_pd(), a2l = _mm256_setzero_pd(), a2h = _mm256_setzero_pd(),
          a3l = _mm256_setzero_pd(), a3h = _mm256_setzero_pd();
  for (int k = 0; k < m; ++k) {
    const __m256d xl = _mm256_loadu_pd(wi + k * kP);
    const __m256d xh = _mm256_loadu_pd(wi + k * kP + 4);
    const double* b = wj + k * kP;
    __m256d y = _mm256_broadcast_sd(b);
    a0l = _mm256_add_pd(a0l, _mm256_mul_pd(xl, y));
    a0h = _mm256_add_pd(a0h, _mm256_mul_pd(xh, y));
    y = _mm256_broadcast_sd(b + 1);
    a1l = _mm256_add_pd(a1l, _mm256_mul_pd(xl, y));
    a1h = _mm256_add_pd(a1h, _mm256_mul_pd(xh, y));
    y = _mm256_broadcast_sd(b + 2);
    a2l = _mm256_add_pd(a2l, _mm256_mul_pd(xl, y));
    a2h = _mm256_add_pd(a2h, _mm256_mul_pd(xh, y));
    y = _mm256_broadcast_sd(b + 3);
    a3l = _mm256_add_pd(a3l, _mm256_mul_pd(xl, y));
    a3h = _mm256_add_pd(a3h, _mm256_mul_pd(xh, y));
  }
  if (p == j0 / kP) {
    // The tile holds the diagonal: element by element, lower triangle only.
    alignas(32) double acc[kTileCols][kP];
    _mm256_store_pd(acc[0], a0l);
    _mm256_store_pd(acc[0] + 4, a0h);
    _mm256_store_pd(acc[1], a1l);
    _mm256_store_pd(acc[1] + 4, a1h);
    _mm256_store_pd(acc[2], a2l);
    _mm256_store_pd(acc[2] + 4, a2h);
    _mm256_store_pd(acc[3], a3l);
    _mm256_store_pd(acc[3] + 4, a3h);
    write_tile(P, ldP, active, i0, j0, acc);
    return;
  }
  // Strictly below the diagonal: P(rows, cols) −= acc column by column, then the 4 × 8 transpose onto
  // P(cols, rows).
  const LaneGroup& gl = active.groups[2 * p];
  const LaneGroup& gh = active.groups[2 * p + 1];
  if (cols_contiguous && full_group(gl) && full_group(gh) && gh.base[0] == gl.base[0] + kGroupLanes) {
    // 8 consecutive covariance rows and 4 consecutive columns (most tiles): plain loads and stores.
    const std::int64_t pi = gl.base[0];
    double* c0 = P + col_row[0] * ldP + pi;
    double* c1 = c0 + ldP;
    double* c2 = c1 + ldP;
    double* c3 = c2 + ldP;
    const __m256d v0l = _mm256_sub_pd(_mm256_loadu_pd(c0), a0l);
    const __m256d v0h = _mm256_sub_pd(_mm256_loadu_pd(c0 + 4), a0h);
    const __m256d v1l = _mm256_sub_pd(_mm256_loadu_pd(c1), a1l);
    const __m256d v1h = _mm256_sub_pd(_mm256_loadu_pd(c1 + 4), a1h);
    const __m256d v2l = _mm256_sub_pd(_mm256_loadu_pd(c2), a2l);
    const __m256d v2h = _mm256_sub_pd(_mm256_loadu_pd(c2 + 4), a2h);
    const __m256d v3l = _mm256_sub_pd(_mm256_loadu_pd(c3), a3l);
    const __m256d v3h = _mm256_sub_pd(_mm256_loadu_pd(c3 + 4), a3h);
    _mm256_storeu_pd(c0, v0l);
    _mm256_storeu_pd(c0 + 4, v0h);
    _mm256_storeu_pd(c1, v1l);
    _mm256_storeu_pd(c1 + 4, v1h);
    _mm256_storeu_pd(c2, v2l);
    _mm256_storeu_pd(c2 + 4, v2h);
    _mm256_storeu_pd(c3, v3l);
    _mm256_storeu_pd(c3 + 4, v3h);
    double* m0 = P + pi * ldP + col_row[0];  // P(cols, row pi)
    transpose_store(m0, ldP, v0l, v1l, v2l, v3l);
    transpose_store(m0 + 4 * ldP, ldP, v0h, v1h, v2h, v3h);
    return;
  }
  // Across holes: each half-panel still one register, by masked loads and stores.
  __m256d v[kTileCols][2];
  const __m256d acc[kTileCols][2] = {{a0l, a0h}, {a1l, a1h}, {a2l, a2h}, {a3l, a3h}};
  for (int c = 0; c < kTileCols; ++c) {
    double* col = P + col_row[c] * ldP;
    v[c][0] = _mm256_sub_pd(load_group(col, gl), acc[c][0]);
    v[c][1] = _mm256_sub_pd(load_group(col, gh), acc[c][1]);
  }
  const unsigned valid_cols = gc.mask[0] | gc.mask[1] | gc.mask[2] | gc.mask[3];
  for (int c = 0; c < kTileCols; ++c) {
    if (!(valid_cols & (1u << c))) continue;
    double* col = P + col_row[c] * ldP;
    store_group(col, gl, v[c][0]);
    store_group(col, gh, v[c][1]);
  }
  for (int h = 0; h < 2; ++h) {
    const __m256d t0 = _mm256_unpacklo_pd(v[0][h], v[1][h]), t1 = _mm256_unpackhi_pd(v[0][h], v[1][h]);
    const __m256d t2 = _mm256_unpacklo_pd(v[2][h], v[3][h]), t3 = _mm256_unpackhi_pd(v[2][h], v[3][h]);
    const __m256d row_v[4] = {_mm256_permute2f128_pd(t0, t2, 0x20), _mm256_permute2f128_pd(t1, t3, 0x20),
                              _mm256_permute2f128_pd(t0, t2, 0x31), _mm256_permute2f128_pd(t1, t3, 0x31)};
    for (int r = 0; r < kGroupLanes; ++r) {
      const int i = i0 + h * kGroupLanes + r;
      if (i >= n) break;
      store_group(P + static_cast<std::int64_t>(rows[i]) * ldP, gc, row_v[r]);
    }
  }
}

// Tiles in the order of 8-column strips, both 4-column halves of a strip at each panel: the halves' mirror stores
// (P(cols, rows), rows of P) fill the two halves of the same cache lines back to back, which the column-by-column
// order wrote a whole sweep apart (P is larger than the L2 cache, so each line was fetched twice). Every element is
// computed as before.
RTSLAM_FILTER_AVX2 void downdate_avx2(double* P, std::int64_t ldP, ActiveRows active, const double* W, int m,
                                      int w_stride) {
  const int n = active.n;
  const int* rows = active.rows;
  const int np = panel_count(n);
  static_assert(2 * kTileCols == kP, "a strip is one panel wide");
  for (int s0 = 0; s0 < n; s0 += kP) {
    TileColumns tc[2];
    int halves = 0;
    for (int j0 = s0; j0 < n && j0 < s0 + kP; j0 += kTileCols) {
      TileColumns& t = tc[halves++];
      t.j0 = j0;
      t.wj = W + static_cast<std::int64_t>(j0 / kP) * w_stride * kP + j0 % kP;
      t.gc = &active.groups[j0 / kGroupLanes];
      t.contiguous = full_group(*t.gc);
      for (int c = 0; c < kTileCols; ++c) t.col_row[c] = j0 + c < n ? rows[j0 + c] : rows[j0];
    }
    for (int p = s0 / kP; p < np; ++p)
      for (int h = 0; h < halves; ++h) downdate_tile(P, ldP, active, W, m, w_stride, tc[h], p);
  }
  _mm256_zeroupper();
}

#endif  // __x86_64__

}  // namespace

void add_P_Ht(ConstMatrixView P, ActiveRows active, int c0, const int* cols, int ncols, ConstMatrixView H, int h0,
              int k0, int k1, double* W, int m) {
#if defined(__x86_64__)
  if (kernel_isa() == KernelIsa::avx2) return add_P_Ht_avx2(P, active, c0, cols, ncols, H, h0, k0, k1, W, m);
#endif
  add_P_Ht_generic(P, active, c0, cols, ncols, H, h0, k0, k1, W, m);
}

void solve_lower_transposed(double* W, int n, int m, ConstMatrixView L) {
#if defined(__x86_64__)
  if (kernel_isa() == KernelIsa::avx2) return solve_avx2(W, n, m, L);
#endif
  solve_generic(W, n, m, L);
}

void subtract_product(double* W, int n, int m, const double* U, int mu, int u_stride, ConstMatrixView G) {
#if defined(__x86_64__)
  if (kernel_isa() == KernelIsa::avx2) return subtract_product_avx2(W, n, m, U, mu, u_stride, G);
#endif
  subtract_product_generic(W, n, m, U, mu, u_stride, G);
}

void downdate_mirrored(double* P, std::int64_t ldP, ActiveRows active, const double* W, int m, int w_stride) {
#if defined(__x86_64__)
  if (kernel_isa() == KernelIsa::avx2) return downdate_avx2(P, ldP, active, W, m, w_stride);
#endif
  downdate_generic(P, ldP, active, W, m, w_stride);
}

}  // namespace kernels
}  // namespace rtslam::filter
