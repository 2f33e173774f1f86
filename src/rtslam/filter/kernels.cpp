#include "rtslam/filter/kernels.hpp"

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <string>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"

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
  if (!__builtin_cpu_supports("fma")) return KernelIsa::avx2;
  return __builtin_cpu_supports("avx512f") ? KernelIsa::avx512 : KernelIsa::avx2_fma;
#else
  return KernelIsa::generic;
#endif
}

std::atomic<KernelIsa>& current() {
  static std::atomic<KernelIsa> isa{kernel_isa_from_env(std::getenv("RTSLAM_KERNEL_ISA"))};
  return isa;
}

}  // namespace

KernelIsa best_kernel_isa() {
  static const KernelIsa best = detect();
  return best;
}

std::optional<KernelIsa> parse_kernel_isa(std::string_view name) {
  for (const KernelIsa isa : {KernelIsa::generic, KernelIsa::avx2, KernelIsa::avx2_fma, KernelIsa::avx512}) {
    if (name == to_string(isa)) return isa;
  }
  return std::nullopt;
}

KernelIsa kernel_isa_from_env(const char* value) {
  if (value == nullptr || *value == '\0') return best_kernel_isa();
  const auto isa = parse_kernel_isa(value);
  if (!isa) {
    throw ConfigError(fmt::format("RTSLAM_KERNEL_ISA: '{}' is not an instruction set of the filter kernels (generic, "
                                  "avx2, avx2_fma or avx512)",
                                  value));
  }
  return static_cast<int>(*isa) < static_cast<int>(best_kernel_isa()) ? *isa : best_kernel_isa();
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
    case KernelIsa::avx2_fma: return "avx2_fma";
    case KernelIsa::avx512: return "avx512";
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

void block_gram_generic(const double* W, int m, int w_stride, int i0, int t, double* G, int ldG) {
  for (int c = 0; c < t; ++c) {
    const int j = i0 + c;
    const double* wj = W + static_cast<std::int64_t>(j / kP) * w_stride * kP + j % kP;
    for (int r = c; r < t; ++r) {
      const int i = i0 + r;
      const double* wi = W + static_cast<std::int64_t>(i / kP) * w_stride * kP + i % kP;
      double acc = 0.0;
      for (int k = 0; k < m; ++k) acc += wi[k * kP] * wj[k * kP];
      G[r + static_cast<std::int64_t>(c) * ldG] = acc;
    }
  }
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

// The columns s0 .. s0 + 7 of a strip (s0 a multiple of kP) as one or two halves of kTileCols; returns the halves.
RTSLAM_FILTER_AVX2 inline int strip_columns(ActiveRows active, const double* W, int w_stride, int s0,
                                            TileColumns (&tc)[2]) {
  static_assert(2 * kTileCols == kP, "a strip is one panel wide");
  const int n = active.n;
  int halves = 0;
  for (int j0 = s0; j0 < n && j0 < s0 + kP; j0 += kTileCols) {
    TileColumns& t = tc[halves++];
    t.j0 = j0;
    t.wj = W + static_cast<std::int64_t>(j0 / kP) * w_stride * kP + j0 % kP;
    t.gc = &active.groups[j0 / kGroupLanes];
    t.contiguous = full_group(*t.gc);
    for (int c = 0; c < kTileCols; ++c) t.col_row[c] = j0 + c < n ? active.rows[j0 + c] : active.rows[j0];
  }
  return halves;
}

// block_gram on every AVX2 level (plain multiplies and adds, as block_gram_generic): the block's rows by lane groups
// of four against its columns four at a time, one accumulator per column; rows before i0 or past the block and
// columns past it are computed from valid memory (the panel, the block's last column) and not written.
RTSLAM_FILTER_AVX2 void block_gram_avx2(const double* W, int m, int w_stride, int i0, int t, double* G, int ldG) {
  const auto packed = [W, w_stride](int i) {
    return W + static_cast<std::int64_t>(i / kP) * w_stride * kP + i % kP;
  };
  const int last = i0 + t - 1;
  for (int g = i0 / kGroupLanes; g <= last / kGroupLanes; ++g) {
    const double* wg = packed(g * kGroupLanes);
    const int row_end = std::min(last, g * kGroupLanes + kGroupLanes - 1);  // the group's last row in the block
    for (int j0 = i0; j0 <= row_end; j0 += kTileCols) {
      const double* wc[kTileCols];
      for (int c = 0; c < kTileCols; ++c) wc[c] = packed(std::min(j0 + c, last));
      __m256d acc0 = _mm256_setzero_pd(), acc1 = acc0, acc2 = acc0, acc3 = acc0;
      for (int k = 0; k < m; ++k) {
        const __m256d a = _mm256_loadu_pd(wg + k * kP);
        acc0 = _mm256_add_pd(acc0, _mm256_mul_pd(a, _mm256_broadcast_sd(wc[0] + k * kP)));
        acc1 = _mm256_add_pd(acc1, _mm256_mul_pd(a, _mm256_broadcast_sd(wc[1] + k * kP)));
        acc2 = _mm256_add_pd(acc2, _mm256_mul_pd(a, _mm256_broadcast_sd(wc[2] + k * kP)));
        acc3 = _mm256_add_pd(acc3, _mm256_mul_pd(a, _mm256_broadcast_sd(wc[3] + k * kP)));
      }
      alignas(32) double sums[kTileCols][kGroupLanes];
      _mm256_store_pd(sums[0], acc0);
      _mm256_store_pd(sums[1], acc1);
      _mm256_store_pd(sums[2], acc2);
      _mm256_store_pd(sums[3], acc3);
      for (int c = 0; c < kTileCols && j0 + c <= row_end; ++c) {
        const int j = j0 + c;
        for (int l = 0; l < kGroupLanes; ++l) {
          const int i = g * kGroupLanes + l;
          if (i >= j && i <= last) G[(i - i0) + static_cast<std::int64_t>(j - i0) * ldG] = sums[c][l];
        }
      }
    }
  }
  _mm256_zeroupper();
}

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

// The downdate in AVX-512 (KernelIsa::avx512): a panel's 8 rows are one register, and a tile is two panels (16
// rows) against a whole strip (8 columns): 16 accumulators, 10 loads for 16 fused multiply-adds, where the AVX2 tile
// (8 rows × 4 columns) needs 6 loads for 8 and, with two FMA units, stays at half the width. Every element is the
// AVX2 + FMA variant's sum, fused in the same k order from zero, and the write-back only subtracts it, so the
// results are the avx2_fma ones, bit for bit. Tiles below the diagonal are written and mirrored in whole registers
// (masked across holes in the active rows); the diagonal tiles go through avx2_fma::downdate_write. The other kernels (about a third of the downdate's time together) use the avx2_fma
// versions.
#define RTSLAM_FILTER_AVX512 __attribute__((target("avx512f,avx2,fma")))
// GCC 12's AVX-512 intrinsics pass an "undefined" register as the unused source of their unmasked forms and then warn
// that it is (or "may be") used uninitialized (GCC bug 105593).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
namespace avx512 {

// The 8 lanes of a panel (or of a strip's 8 columns) as runs of consecutive covariance rows: lane L of run s is row
// off[s] + L, for the lanes of mask[s] (lanes past the active rows are in none). Built from the two lane groups.
struct PanelRuns {
  int count = 0;
  std::int64_t off[kP] = {};
  __mmask8 mask[kP] = {};
};

inline PanelRuns panel_runs(const LaneGroup& lo, const LaneGroup& hi) {
  PanelRuns r;
  for (int h = 0; h < 2; ++h) {
    const LaneGroup& g = h == 0 ? lo : hi;
    for (int s = 0; s < g.segments; ++s) {
      const std::int64_t off = g.base[s] - h * kGroupLanes;
      const auto mask = static_cast<__mmask8>(g.mask[s] << (h * kGroupLanes));
      if (r.count > 0 && r.off[r.count - 1] == off) {
        r.mask[r.count - 1] = static_cast<__mmask8>(r.mask[r.count - 1] | mask);  // a run across the two groups
      } else {
        r.off[r.count] = off;
        r.mask[r.count++] = mask;
      }
    }
  }
  return r;
}

// The lanes of v at base + run offsets (masked loads: the lanes of no run are zero, and nothing outside the runs
// is read; AVX-512 masked accesses do not fault on masked-out lanes).
RTSLAM_FILTER_AVX512 inline __m512d load_runs(const double* base, const PanelRuns& r) {
  __m512d v = _mm512_setzero_pd();
  for (int s = 0; s < r.count; ++s) v = _mm512_mask_loadu_pd(v, r.mask[s], base + r.off[s]);
  return v;
}

RTSLAM_FILTER_AVX512 inline void store_runs(double* base, const PanelRuns& r, __m512d v) {
  for (int s = 0; s < r.count; ++s) _mm512_mask_storeu_pd(base + r.off[s], r.mask[s], v);
}

// The 8 × 8 transpose: out[r] lane c = in[c] lane r.
RTSLAM_FILTER_AVX512 inline void transpose8(const __m512d (&in)[kP], __m512d (&out)[kP]) {
  __m512d t[kP], u[kP];
  for (int c = 0; c < kP; c += 2) {
    t[c] = _mm512_unpacklo_pd(in[c], in[c + 1]);
    t[c + 1] = _mm512_unpackhi_pd(in[c], in[c + 1]);
  }
  for (int q = 0; q < kP; q += 4) {
    u[q] = _mm512_shuffle_f64x2(t[q], t[q + 2], 0x88);
    u[q + 1] = _mm512_shuffle_f64x2(t[q + 1], t[q + 3], 0x88);
    u[q + 2] = _mm512_shuffle_f64x2(t[q], t[q + 2], 0xDD);
    u[q + 3] = _mm512_shuffle_f64x2(t[q + 1], t[q + 3], 0xDD);
  }
  for (int r = 0; r < 4; ++r) {
    out[r] = _mm512_shuffle_f64x2(u[r], u[r + 4], 0x88);
    out[r + 4] = _mm512_shuffle_f64x2(u[r], u[r + 4], 0xDD);
  }
}

// Writes panel p's tiles of the strip from its 8 column accumulators (column c: lanes = the panel's rows).
// cols: the strip's columns as runs (used when halves == 2).
RTSLAM_FILTER_AVX512 inline void write_strip_panel(double* P, std::int64_t ldP, ActiveRows active,
                                                   const TileColumns (&tc)[2], int halves, const PanelRuns& cols,
                                                   int p, const __m512d (&acc)[kP]) {
  const LaneGroup& gl = active.groups[2 * p];
  const LaneGroup& gh = active.groups[2 * p + 1];
  if (halves == 2 && p != tc[0].j0 / kP) {
    // Strictly below the diagonal, against the strip's 8 columns: P(rows, cols) −= acc a column at a time, then the
    // 8 × 8 transpose onto P(cols, rows), a row at a time, in whole registers.
    __m512d v[kP], t[kP];
    if (tc[0].contiguous && tc[1].contiguous && tc[1].col_row[0] == tc[0].col_row[0] + kTileCols &&
        full_group(gl) && full_group(gh) && gh.base[0] == gl.base[0] + kGroupLanes) {
      // 8 consecutive rows and 8 consecutive columns (most tiles): plain loads and stores.
      const std::int64_t pi = gl.base[0];
      const std::int64_t pj = tc[0].col_row[0];
      for (int c = 0; c < kP; ++c) {
        double* col = P + (pj + c) * ldP + pi;
        v[c] = _mm512_sub_pd(_mm512_loadu_pd(col), acc[c]);
        _mm512_storeu_pd(col, v[c]);
      }
      transpose8(v, t);
      double* m0 = P + pi * ldP + pj;  // P(cols, row pi)
      for (int r = 0; r < kP; ++r) _mm512_storeu_pd(m0 + r * ldP, t[r]);
      return;
    }
    // Across holes: masked loads and stores of the runs of rows, and of columns for the mirror.
    const PanelRuns rows = panel_runs(gl, gh);
    // The strip's 8 columns are all active here: only the last strip has fewer, and its one panel is the diagonal's.
    for (int c = 0; c < kP; ++c) {
      double* col = P + tc[c / kTileCols].col_row[c % kTileCols] * ldP;
      v[c] = _mm512_sub_pd(load_runs(col, rows), acc[c]);
      store_runs(col, rows, v[c]);
    }
    transpose8(v, t);
    const int i0 = p * kP;
    for (int r = 0; r < kP && i0 + r < active.n; ++r) {
      store_runs(P + static_cast<std::int64_t>(active.rows[i0 + r]) * ldP, cols, t[r]);
    }
    return;
  }
  for (int h = 0; h < halves; ++h) {
    __m256d a[kTileCols][2];
    for (int c = 0; c < kTileCols; ++c) {
      a[c][0] = _mm512_castpd512_pd256(acc[h * kTileCols + c]);
      a[c][1] = _mm512_extractf64x4_pd(acc[h * kTileCols + c], 1);
    }
    avx2_fma::downdate_write(P, ldP, active, tc[h], p, a);
  }
}

RTSLAM_FILTER_AVX512 void downdate_avx512(double* P, std::int64_t ldP, ActiveRows active, const double* W, int m,
                                          int w_stride) {
  const int n = active.n;
  const int np = panel_count(n);
  for (int s0 = 0; s0 < n; s0 += kP) {
    TileColumns tc[2];
    const int halves = strip_columns(active, W, w_stride, s0, tc);
    const PanelRuns cols = halves == 2 ? panel_runs(*tc[0].gc, *tc[1].gc) : PanelRuns{};
    // W(s0 + c, k) for the strip's 8 columns (lanes past n may hold anything: their sums are never written).
    const double* wj = W + static_cast<std::int64_t>(s0 / kP) * w_stride * kP;
    int p = s0 / kP;
    for (; p + 1 < np; p += 2) {
      const double* wa = W + static_cast<std::int64_t>(p) * w_stride * kP;
      const double* wb = wa + static_cast<std::int64_t>(w_stride) * kP;
      __m512d a[kP], b[kP];
      for (int c = 0; c < kP; ++c) a[c] = b[c] = _mm512_setzero_pd();
      for (int k = 0; k < m; ++k) {
        const __m512d xa = _mm512_loadu_pd(wa + k * kP);
        const __m512d xb = _mm512_loadu_pd(wb + k * kP);
        const double* y = wj + k * kP;
        for (int c = 0; c < kP; ++c) {
          const __m512d yc = _mm512_set1_pd(y[c]);
          a[c] = _mm512_fmadd_pd(xa, yc, a[c]);
          b[c] = _mm512_fmadd_pd(xb, yc, b[c]);
        }
      }
      write_strip_panel(P, ldP, active, tc, halves, cols, p, a);
      write_strip_panel(P, ldP, active, tc, halves, cols, p + 1, b);
    }
    if (p < np) {  // an odd panel left: one panel against the strip
      const double* wa = W + static_cast<std::int64_t>(p) * w_stride * kP;
      __m512d a[kP];
      for (int c = 0; c < kP; ++c) a[c] = _mm512_setzero_pd();
      for (int k = 0; k < m; ++k) {
        const __m512d xa = _mm512_loadu_pd(wa + k * kP);
        const double* y = wj + k * kP;
        for (int c = 0; c < kP; ++c) a[c] = _mm512_fmadd_pd(xa, _mm512_set1_pd(y[c]), a[c]);
      }
      write_strip_panel(P, ldP, active, tc, halves, cols, p, a);
    }
  }
  _mm256_zeroupper();
}

}  // namespace avx512
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
#undef RTSLAM_FILTER_AVX512
#undef RTSLAM_FILTER_AVX2

#endif  // __x86_64__

}  // namespace

void add_P_Ht(ConstMatrixView P, ActiveRows active, int c0, const int* cols, int ncols, ConstMatrixView H, int h0,
              int k0, int k1, double* W, int m) {
#if defined(__x86_64__)
  switch (kernel_isa()) {
    case KernelIsa::avx512:
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
    case KernelIsa::avx512:
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
    case KernelIsa::avx512:
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

void block_gram(const double* W, int m, int w_stride, int i0, int t, double* G, int ldG) {
#if defined(__x86_64__)
  if (kernel_isa() != KernelIsa::generic) return block_gram_avx2(W, m, w_stride, i0, t, G, ldG);
#endif
  block_gram_generic(W, m, w_stride, i0, t, G, ldG);
}

void downdate_mirrored(double* P, std::int64_t ldP, ActiveRows active, const double* W, int m, int w_stride) {
#if defined(__x86_64__)
  switch (kernel_isa()) {
    case KernelIsa::avx512:
      return avx512::downdate_avx512(P, ldP, active, W, m, w_stride);
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
