#include "rtslam/vision/zncc.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/LU>

#include "rtslam/vision/peak.hpp"
#include "rtslam/vision/simd.hpp"

#if defined(__x86_64__)
#include <emmintrin.h>
#endif

namespace rtslam::vision {

// ---------------------------------------------------------------------------------------------------------------
// Patch

void Patch::assign(ImageView src) {
  RTSLAM_CHECK(src.width == src.height && src.width % 2 == 1 && src.width > 0 && src.data != nullptr,
               "Patch::assign: the view must be square with an odd size");
  size_ = src.width;
  pixels_.resize(static_cast<std::size_t>(size_) * static_cast<std::size_t>(size_));
  for (int v = 0; v < size_; ++v) std::copy_n(src.row(v), size_, pixels_.data() + static_cast<std::size_t>(v) * size_);
  precompute();
}

bool Patch::extract(ImageView image, int u, int v, int size) {
  const int h = size / 2;
  if (size <= 0 || size % 2 == 0 || u - h < 0 || v - h < 0 || u + h >= image.width || v + h >= image.height) {
    return false;
  }
  assign(image.roi(u - h, v - h, size, size));
  return true;
}

void Patch::precompute() {
  const int s = size_;
  suffix_sum_.assign(static_cast<std::size_t>(s) + 1, 0);
  suffix_sq_.assign(static_cast<std::size_t>(s) + 1, 0);
  for (int r = s - 1; r >= 0; --r) {
    std::int64_t rs = 0, rq = 0;
    const std::uint8_t* row = pixels_.data() + static_cast<std::size_t>(r) * s;
    for (int c = 0; c < s; ++c) {
      rs += row[c];
      rq += static_cast<std::int64_t>(row[c]) * row[c];
    }
    suffix_sum_[static_cast<std::size_t>(r)] = suffix_sum_[static_cast<std::size_t>(r) + 1] + rs;
    suffix_sq_[static_cast<std::size_t>(r)] = suffix_sq_[static_cast<std::size_t>(r) + 1] + rq;
  }
  sum_ = suffix_sum_[0];
  sum_sq_ = suffix_sq_[0];
  const std::int64_t n = static_cast<std::int64_t>(s) * s;
  energy_ = n * sum_sq_ - sum_ * sum_;

  // Half resolution: [1 2 1] x [1 2 1] weighted sums centred on the odd pixels 1, 3, .., 2 hs - 1 (so the reduced
  // template is centred on the same pixel as the full one).
  const int hs = s / 2;
  half_stride_ = (hs + 7) / 8 * 8;
  half_.assign(static_cast<std::size_t>(hs) * static_cast<std::size_t>(half_stride_), 0);
  for (int j = 0; j < hs; ++j)
    for (int i = 0; i < hs; ++i) {
      int acc = 0;
      for (int dy = 0; dy < 3; ++dy)
        for (int dx = 0; dx < 3; ++dx)
          acc += (dy == 1 ? 2 : 1) * (dx == 1 ? 2 : 1) * pixels_[static_cast<std::size_t>(2 * j + dy) * s + 2 * i + dx];
      half_[static_cast<std::size_t>(j) * half_stride_ + i] = static_cast<std::int16_t>(acc);
    }
  padded_stride_ = (s + 15) / 16 * 16;
  padded_.assign(static_cast<std::size_t>(s) * static_cast<std::size_t>(padded_stride_), 0);
  for (int j = 0; j < s; ++j)
    for (int i = 0; i < s; ++i)
      padded_[static_cast<std::size_t>(j) * padded_stride_ + i] = pixels_[static_cast<std::size_t>(j) * s + i];
  half_suffix_sum_.assign(static_cast<std::size_t>(hs) + 1, 0);
  half_suffix_sq_.assign(static_cast<std::size_t>(hs) + 1, 0);
  for (int r = hs - 1; r >= 0; --r) {
    std::int64_t rs = 0, rq = 0;
    for (int c = 0; c < hs; ++c) {
      const std::int64_t x = half_[static_cast<std::size_t>(r) * half_stride_ + c];
      rs += x;
      rq += x * x;
    }
    half_suffix_sum_[static_cast<std::size_t>(r)] = half_suffix_sum_[static_cast<std::size_t>(r) + 1] + rs;
    half_suffix_sq_[static_cast<std::size_t>(r)] = half_suffix_sq_[static_cast<std::size_t>(r) + 1] + rq;
  }
  const std::int64_t nh = static_cast<std::int64_t>(hs) * hs;
  half_energy_ = nh * half_suffix_sq_[0] - half_suffix_sum_[0] * half_suffix_sum_[0];
}

// ---------------------------------------------------------------------------------------------------------------
// SearchEllipse

SearchEllipse SearchEllipse::from_covariance(const Eigen::Vector2d& centre, const Eigen::Matrix2d& cov,
                                             double n_sigma) {
  SearchEllipse e;
  e.centre = centre;
  e.inv_cov = cov.inverse();
  e.n_sigma = n_sigma;
  return e;
}

SearchEllipse SearchEllipse::box(const Eigen::Vector2d& centre, double half_w, double half_h) {
  SearchEllipse e;
  e.centre = centre;
  e.box_only = true;
  e.box_half = Eigen::Vector2d(std::max(half_w, 0.0), std::max(half_h, 0.0));
  return e;
}

bool SearchEllipse::contains(double u, double v) const {
  const double du = u - centre.x(), dv = v - centre.y();
  if (box_only) return std::abs(du) <= box_half.x() && std::abs(dv) <= box_half.y();
  const double n2 = n_sigma * n_sigma;
  const double d2 = inv_cov(0, 0) * du * du + (inv_cov(0, 1) + inv_cov(1, 0)) * du * dv + inv_cov(1, 1) * dv * dv;
  return d2 <= n2;
}

Roi SearchEllipse::bounding_box() const {
  double ext_u = box_half.x(), ext_v = box_half.y();
  if (!box_only) {
    // Extent of the ellipse along u: n sqrt(cov_uu), with cov = inv_cov⁻¹ (cov_uu = inv_vv / det).
    const double det = inv_cov(0, 0) * inv_cov(1, 1) - inv_cov(0, 1) * inv_cov(1, 0);
    if (!(det > 0.0) || !(n_sigma >= 0.0)) return Roi{};
    ext_u = n_sigma * std::sqrt(inv_cov(1, 1) / det);
    ext_v = n_sigma * std::sqrt(inv_cov(0, 0) / det);
  }
  if (!std::isfinite(ext_u) || !std::isfinite(ext_v)) return Roi{};
  constexpr double kMax = 1e6;  // keeps absurd ellipses representable
  const double u0 = std::ceil(std::max(centre.x() - ext_u, -kMax)), u1 = std::floor(std::min(centre.x() + ext_u, kMax));
  const double v0 = std::ceil(std::max(centre.y() - ext_v, -kMax)), v1 = std::floor(std::min(centre.y() + ext_v, kMax));
  if (u1 < u0 || v1 < v0) return Roi{};
  return Roi{static_cast<int>(u0), static_cast<int>(v0), static_cast<int>(u1 - u0) + 1, static_cast<int>(v1 - v0) + 1};
}

// ---------------------------------------------------------------------------------------------------------------
// Options

void ZnccOptions::validate(const std::string& where) const {
  require_bound(threshold >= -1.0 && threshold <= 1.0, where, "threshold", threshold, "in [-1, 1]");
  require_bound(patch_size >= 5 && patch_size <= 31 && patch_size % 2 == 1, where, "patch_size", patch_size,
                "odd and in [5, 31]");
  require_bound(coarse_margin >= 0.0 && coarse_margin <= 2.0, where, "coarse_margin", coarse_margin, "in [0, 2]");
  require_bound(coarse_candidates_spread >= 0.0 && coarse_candidates_spread <= 2.0, where, "coarse_candidates_spread",
                coarse_candidates_spread, "in [0, 2]");
  require_bound(climb_radius >= 1 && climb_radius <= 3, where, "climb_radius", climb_radius, "in [1, 3]");
  require_bound(partial_step_rows >= 1 && partial_step_rows <= patch_size, where, "partial_step_rows",
                partial_step_rows, "in [1, patch_size]");
}

ZnccOptions ZnccOptions::from_yaml(YamlMap& map) {
  ZnccOptions o;
  map.get("threshold", o.threshold);
  map.get("patch_size", o.patch_size);
  map.get("two_level", o.two_level);
  map.get("partial_correlation", o.partial_correlation);
  map.get("coarse_margin", o.coarse_margin);
  map.get("coarse_candidates_spread", o.coarse_candidates_spread);
  map.get("climb_radius", o.climb_radius);
  map.get("partial_step_rows", o.partial_step_rows);
  map.finish();
  o.validate(map.where());
  return o;
}

YAML::Node ZnccOptions::to_yaml() const {
  YAML::Node n;
  n["threshold"] = threshold;
  n["patch_size"] = patch_size;
  n["two_level"] = two_level;
  n["partial_correlation"] = partial_correlation;
  n["coarse_margin"] = coarse_margin;
  n["coarse_candidates_spread"] = coarse_candidates_spread;
  n["climb_radius"] = climb_radius;
  n["partial_step_rows"] = partial_step_rows;
  return n;
}

// ---------------------------------------------------------------------------------------------------------------
// Matcher

void ScoreMemo::reserve(int capacity) {
  RTSLAM_CHECK(capacity >= 1 && capacity <= (1 << 20), "ScoreMemo: capacity out of [1, 2^20]");
  std::size_t n = 1;
  while (n < static_cast<std::size_t>(capacity)) n *= 2;
  entries_.assign(n, Entry{});
  generation_ = 1;
  size_ = 0;
}

void ScoreMemo::clear() {
  size_ = 0;
  if (++generation_ == 0) {  // wrapped: no stale entry may look current
    for (Entry& e : entries_) e.generation = 0;
    generation_ = 1;
  }
}

std::size_t ScoreMemo::home(std::uint64_t key) const {
  return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> 40) & (entries_.size() - 1);
}

namespace {
std::uint64_t memo_key(int u, int v) {
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(u)) << 32) | static_cast<std::uint32_t>(v);
}
}  // namespace

// Linear probing from the key's home: the key's entry, or the empty slot that ends its chain; npos if neither (a
// memo never reserved; the half-load limit keeps a reserved one from filling).
std::size_t ScoreMemo::slot(std::uint64_t key) const {
  const std::size_t mask = entries_.size() - 1;
  for (std::size_t i = entries_.empty() ? 0 : home(key), probes = 0; probes < entries_.size();
       i = (i + 1) & mask, ++probes) {
    if (entries_[i].generation != generation_ || entries_[i].key == key) return i;
  }
  return npos;
}

bool ScoreMemo::lookup(int u, int v, double& value, bool& exact) const {
  const std::uint64_t key = memo_key(u, v);
  const std::size_t i = slot(key);
  if (i == npos || entries_[i].generation != generation_) return false;
  value = entries_[i].value;
  exact = entries_[i].is_exact;
  return true;
}

void ScoreMemo::remember(int u, int v, double value, bool exact) {
  const std::uint64_t key = memo_key(u, v);
  const std::size_t i = slot(key);
  if (i == npos) return;
  Entry& e = entries_[i];
  if (e.generation != generation_) {
    if (2 * (size_ + 1) > static_cast<int>(entries_.size())) return;  // at half load: stop remembering
    e = Entry{key, value, generation_, exact};
    ++size_;
  } else if (!e.is_exact && (exact || value < e.value)) {  // an exact score is never replaced; a floor by a lower one
    e.value = value;
    e.is_exact = exact;
  }
}

ZnccMatcher::ZnccMatcher(ZnccOptions options) : options_(options) { options_.validate(); }

namespace {

constexpr double kBoundMargin = 1e-12;  // covers the rounding of the bound and of the score (~1e-15)

// Kernels, in plain C++ and SSE2 (the x86-64 baseline), chosen by simd_level(). Both give the same exact integer sums.
//
// Exactness of the int32/uint32 accumulations:
//  - full resolution: Σ ab <= 31² * 255² < 2^31;
//  - half resolution: reduced pixels and template entries are [1 2 1]² sums, 0 .. 4080, with at most 15 x 15 of
//    them (patch <= 31): Σ ab and Σ b² over a window are < 225 * 4080² < 2^32, accumulated as uint32 (all terms are
//    non-negative); the half-resolution integral tables are uint32 modulo 2^32, exact for any such window.

// Horizontal [1 2 1] reduction at stride 2: dst[i] = src[2i] + 2 src[2i + 1] + src[2i + 2] for i in [0, n).
void reduce_row(const std::uint8_t* src, int n, std::uint16_t* dst, bool simd) {
  int i = 0;
#if defined(__x86_64__)
  if (simd) {
    const __m128i low_bytes = _mm_set1_epi16(0x00FF);
    for (; i + 9 <= n; i += 8) {  // reads src[2i, 2i + 18), inside [0, 2n]
      const __m128i v0 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + 2 * i));
      const __m128i v1 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + 2 * i + 2));
      const __m128i odd = _mm_srli_epi16(v0, 8);
      const __m128i sum = _mm_add_epi16(_mm_add_epi16(_mm_and_si128(v0, low_bytes), _mm_and_si128(v1, low_bytes)),
                                        _mm_add_epi16(odd, odd));
      _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + i), sum);
    }
  }
#else
  (void)simd;
#endif
  for (; i < n; ++i) dst[i] = static_cast<std::uint16_t>(src[2 * i] + 2 * src[2 * i + 1] + src[2 * i + 2]);
}

// One row of the half-resolution integral tables, modulo 2^32: S[i + 1] = Sp[i + 1] + Σ_{i'<=i} v[i'], Q likewise
// with squares, for i in [0, n) (the caller sets S[0] and Q[0]).
void half_table_row(const std::int16_t* v, int n, const std::uint32_t* Sp, std::uint32_t* S, const std::uint32_t* Qp,
                    std::uint32_t* Q, bool simd) {
  int i = 0;
  std::uint32_t rs = 0, rq = 0;
#if defined(__x86_64__)
  if (simd) {
    const __m128i zero = _mm_setzero_si128();
    __m128i carry_s = zero, carry_q = zero;
    auto prefix4 = [](__m128i x) {
      x = _mm_add_epi32(x, _mm_slli_si128(x, 4));
      return _mm_add_epi32(x, _mm_slli_si128(x, 8));
    };
    auto last = [](__m128i x) { return _mm_shuffle_epi32(x, _MM_SHUFFLE(3, 3, 3, 3)); };
    auto store = [](std::uint32_t* d, const std::uint32_t* p, __m128i x) {
      _mm_storeu_si128(reinterpret_cast<__m128i*>(d),
                       _mm_add_epi32(x, _mm_loadu_si128(reinterpret_cast<const __m128i*>(p))));
    };
    for (; i + 8 <= n; i += 8) {
      const __m128i x = _mm_loadu_si128(reinterpret_cast<const __m128i*>(v + i));
      // Sums: 16-bit prefixes first (at most 8 * 4080).
      __m128i c = _mm_add_epi16(x, _mm_slli_si128(x, 2));
      c = _mm_add_epi16(c, _mm_slli_si128(c, 4));
      c = _mm_add_epi16(c, _mm_slli_si128(c, 8));
      const __m128i s0 = _mm_add_epi32(_mm_unpacklo_epi16(c, zero), carry_s);
      const __m128i s1 = _mm_add_epi32(_mm_unpackhi_epi16(c, zero), carry_s);
      carry_s = last(s1);
      store(S + i + 1, Sp + i + 1, s0);
      store(S + i + 5, Sp + i + 5, s1);
      // Squares: (v, 0) int16 pairs through pmaddwd.
      const __m128i x0 = _mm_unpacklo_epi16(x, zero), x1 = _mm_unpackhi_epi16(x, zero);
      const __m128i q0 = _mm_add_epi32(prefix4(_mm_madd_epi16(x0, x0)), carry_q);
      const __m128i q1 = _mm_add_epi32(prefix4(_mm_madd_epi16(x1, x1)), last(q0));
      carry_q = last(q1);
      store(Q + i + 1, Qp + i + 1, q0);
      store(Q + i + 5, Qp + i + 5, q1);
    }
    rs = static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry_s));
    rq = static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry_q));
  }
#else
  (void)simd;
#endif
  for (; i < n; ++i) {
    const auto x = static_cast<std::uint32_t>(v[i]);
    rs += x;
    rq += x * x;
    S[i + 1] = Sp[i + 1] + rs;
    Q[i + 1] = Qp[i + 1] + rq;
  }
}

#if defined(__x86_64__)
inline std::uint32_t hsum_epu32(__m128i v) {
  v = _mm_add_epi32(v, _mm_shuffle_epi32(v, _MM_SHUFFLE(1, 0, 3, 2)));
  v = _mm_add_epi32(v, _mm_shuffle_epi32(v, _MM_SHUFFLE(2, 3, 0, 1)));
  return static_cast<std::uint32_t>(_mm_cvtsi128_si32(v));
}
#endif

// Σ ab of the half-resolution template (rows int16, `stride` apart, zero-padded) at n consecutive positions of
// reduced image rows (b_stride apart): out[i] for the window whose top-left entry is b[i]. Reading `stride` entries
// per row must stay inside the buffer.
void half_dots(const std::int16_t* a, int rows, int stride, const std::int16_t* b, std::ptrdiff_t b_stride, int n,
               std::uint32_t* out, bool simd) {
  int i = 0;
#if defined(__x86_64__)
  if (simd && stride == 8) {
    // Four positions per step; their four lane sums are reduced together by a 4 x 4 transpose.
    auto ld = [](const std::int16_t* p) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p)); };
    for (; i + 4 <= n; i += 4) {
      __m128i acc[4] = {_mm_setzero_si128(), _mm_setzero_si128(), _mm_setzero_si128(), _mm_setzero_si128()};
      for (int r = 0; r < rows; ++r) {
        const __m128i ar = ld(a + r * 8);
        const std::int16_t* br = b + r * b_stride + i;
        for (int k = 0; k < 4; ++k) acc[k] = _mm_add_epi32(acc[k], _mm_madd_epi16(ar, ld(br + k)));
      }
      const __m128i t01 = _mm_add_epi32(_mm_unpacklo_epi32(acc[0], acc[1]), _mm_unpackhi_epi32(acc[0], acc[1]));
      const __m128i t23 = _mm_add_epi32(_mm_unpacklo_epi32(acc[2], acc[3]), _mm_unpackhi_epi32(acc[2], acc[3]));
      _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i),
                       _mm_add_epi32(_mm_unpacklo_epi64(t01, t23), _mm_unpackhi_epi64(t01, t23)));
    }
  }
  if (simd) {
    for (; i < n; ++i) {
      __m128i acc = _mm_setzero_si128();
      for (int r = 0; r < rows; ++r)
        for (int k = 0; k < stride; k += 8)
          acc = _mm_add_epi32(
              acc, _mm_madd_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a + r * stride + k)),
                                  _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + r * b_stride + i + k))));
      out[i] = hsum_epu32(acc);
    }
    return;
  }
#else
  (void)simd;
#endif
  for (; i < n; ++i) {
    std::uint32_t acc = 0;
    for (int r = 0; r < rows; ++r)
      for (int k = 0; k < stride; ++k) acc += static_cast<std::uint32_t>(a[r * stride + k] * b[r * b_stride + i + k]);
    out[i] = acc;
  }
}

// Full-resolution kernels. A window is s x s pixels from b (rows b_stride apart); template rows are int16, zero-padded
// to a multiple of 16 entries. A kernel policy provides:
//  - rows(b, b_stride, s, step, sum, sq): Σb and Σb² of the window rows [g step, min(s, (g + 1) step)) for every
//    group g < ceil(s / step) (row sums of squares fit int32: 31 * 65025); returns the number of groups;
//  - dot(a, stride, s, b, b_stride, r0, r1): Σ ab over the rows [r0, r1).
struct ScalarKernel {
  static int rows(const std::uint8_t* b, std::ptrdiff_t b_stride, int s, int step, std::int64_t* sum,
                  std::int64_t* sq) {
    int g = 0;
    for (; g * step < s; ++g) {
      std::int64_t gs = 0, gq = 0;
      for (int r = g * step; r < std::min(s, (g + 1) * step); ++r)
        for (int c = 0; c < s; ++c) {
          const std::int64_t p = b[r * b_stride + c];
          gs += p;
          gq += p * p;
        }
      sum[g] = gs;
      sq[g] = gq;
    }
    return g;
  }
  static std::int64_t dot(const std::int16_t* a, int stride, int s, const std::uint8_t* b, std::ptrdiff_t b_stride,
                          int r0, int r1) {
    std::int64_t acc = 0;
    for (int r = r0; r < r1; ++r)
      for (int c = 0; c < s; ++c) acc += static_cast<std::int32_t>(a[r * stride + c]) * b[r * b_stride + c];
    return acc;
  }
};

#if defined(__x86_64__)
// SSE2, kBlocks 16-byte blocks per row (patches up to 16 or 32 pixels wide); reads the whole padded width of each
// row, so the caller checks that it stays inside the image.
template <int kBlocks>
struct Sse2Kernel {
  static int rows(const std::uint8_t* b, std::ptrdiff_t b_stride, int s, int step, std::int64_t* sum,
                  std::int64_t* sq) {
    // Byte masks of the s used columns: 16 - c bytes into {0xFF x 16, 0 x 16} starts with c 0xFF bytes.
    alignas(16) static constexpr std::uint8_t kMask[32] = {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF,
                                                           0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
    __m128i mask[kBlocks];
    for (int k = 0; k < kBlocks; ++k)
      mask[k] = _mm_loadu_si128(reinterpret_cast<const __m128i*>(kMask + 16 - std::clamp(s - 16 * k, 0, 16)));
    const __m128i zero = _mm_setzero_si128();
    int g = 0;
    for (int r = 0; r < s; ++g) {
      __m128i acc_s = zero, acc_q = zero;
      for (const int end = std::min(s, r + step); r < end; ++r) {
        for (int k = 0; k < kBlocks; ++k) {
          const __m128i v =
              _mm_and_si128(_mm_loadu_si128(reinterpret_cast<const __m128i*>(b + r * b_stride + 16 * k)), mask[k]);
          acc_s = _mm_add_epi64(acc_s, _mm_sad_epu8(v, zero));
          const __m128i lo = _mm_unpacklo_epi8(v, zero), hi = _mm_unpackhi_epi8(v, zero);
          acc_q = _mm_add_epi32(acc_q, _mm_add_epi32(_mm_madd_epi16(lo, lo), _mm_madd_epi16(hi, hi)));
        }
      }
      sum[g] = _mm_cvtsi128_si32(_mm_add_epi32(acc_s, _mm_unpackhi_epi64(acc_s, acc_s)));
      sq[g] = static_cast<std::int32_t>(hsum_epu32(acc_q));
    }
    return g;
  }
  static std::int64_t dot(const std::int16_t* a, int stride, int /*s*/, const std::uint8_t* b, std::ptrdiff_t b_stride,
                          int r0, int r1) {
    const __m128i zero = _mm_setzero_si128();
    __m128i acc = zero;
    for (int r = r0; r < r1; ++r) {
      for (int k = 0; k < kBlocks; ++k) {
        const std::int16_t* ar = a + r * stride + 16 * k;
        const __m128i vb = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + r * b_stride + 16 * k));
        acc = _mm_add_epi32(
            acc, _mm_madd_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(ar)), _mm_unpacklo_epi8(vb, zero)));
        acc = _mm_add_epi32(acc, _mm_madd_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(ar + 8)),
                                                _mm_unpackhi_epi8(vb, zero)));
      }
    }
    return hsum_epu32(acc);
  }
};
#endif

// A full-resolution window: its top-left pixel b (rows b_stride apart), at (x0, y0) in the image. With a table (the
// integral images of the search region), its sums come from the table, else from its rows.
struct Window {
  const std::uint8_t* b;
  std::ptrdiff_t b_stride;
  int x0, y0;
  const IntegralImages* table;
};

// ZNCC of the full-resolution template against a window. With prune, abandons (returns false) when the bound on the
// score falls strictly below floor (minus the rounding margin).
template <class Kernel>
bool zncc_window(const Patch& t, const Window& w, bool prune, int step, double floor, double* score) {
  const int s = t.size();
  if (!prune) step = s;
  std::int64_t rest_sum[32], rest_sq[32];  // sums of the window rows [g step, s) (patch <= 31)
  rest_sum[0] = rest_sq[0] = 0;            // always set below; spares a false -Wmaybe-uninitialized
  // From the table, each group's sums are looked up when its bound is checked.
  auto table_rest = [&](int g) {
    rest_sum[g] = w.table->sum(w.x0, w.y0 + g * step, s, s - g * step);
    rest_sq[g] = static_cast<std::int64_t>(w.table->sum_sq(w.x0, w.y0 + g * step, s, s - g * step));
  };
  if (w.table != nullptr) {
    table_rest(0);
  } else {
    for (int g = Kernel::rows(w.b, w.b_stride, s, step, rest_sum, rest_sq) - 2; g >= 0; --g) {
      rest_sum[g] += rest_sum[g + 1];
      rest_sq[g] += rest_sq[g + 1];
    }
  }
  const std::uint8_t* b = w.b;
  const std::ptrdiff_t b_stride = w.b_stride;
  const std::int64_t n = static_cast<std::int64_t>(s) * s;
  const std::int64_t energy_b = n * rest_sq[0] - rest_sum[0] * rest_sum[0];
  if (energy_b <= 0) {
    *score = 0.0;
    return true;
  }
  const double inv_den = 1.0 / std::sqrt(static_cast<double>(t.centred_energy()) * static_cast<double>(energy_b));
  const double sa_sb = static_cast<double>(t.sum() * rest_sum[0]);
  const double dn = static_cast<double>(n);
  std::int64_t sab = 0;
  for (int g = 1, done = 0; done < s; ++g) {
    const int next = std::min(s, done + step);
    sab += Kernel::dot(t.padded_data(), t.padded_stride(), s, b, b_stride, done, next);
    done = next;
    if (done < s) {
      // Bound of the remaining rows [done, s), m pixels: Cauchy-Schwarz on the centred rows plus the mean term.
      const std::int64_t m = static_cast<std::int64_t>(s - done) * s;
      const std::int64_t sa_r = t.suffix_sum(done);
      const std::int64_t saa_r = t.suffix_sq(done);
      if (w.table != nullptr) table_rest(g);
      const double ea_r = static_cast<double>(m * saa_r - sa_r * sa_r);
      const double eb_r = static_cast<double>(m * rest_sq[g] - rest_sum[g] * rest_sum[g]);
      const double rest = (std::sqrt(ea_r * eb_r) + static_cast<double>(sa_r * rest_sum[g])) / static_cast<double>(m);
      const double bound = (dn * (static_cast<double>(sab) + rest) - sa_sb) * inv_den;
      if (bound < floor - kBoundMargin) return false;
    }
  }
  *score = static_cast<double>(n * sab - t.sum() * rest_sum[0]) * inv_den;
  return true;
}

}  // namespace

void ZnccMatcher::reserve(double max_area_px2, int width, int height) {
  RTSLAM_CHECK(max_area_px2 > 0.0 && width > 0 && height > 0, "ZnccMatcher::reserve: empty bounds");
  const int h = options_.patch_size / 2;
  const int hs = (options_.patch_size + 1) / 2;  // upper bound of the half-resolution template size
  const int max_w = std::max(1, width - 2 * h), max_h = std::max(1, height - 2 * h);
  // Every buffer size is a function of the box's width and height; scan the widths, each with the tallest box the
  // area allows, and keep the largest need of each buffer.
  std::size_t n_pos = 0, n_rows = 0, n_half = 0, n_table = 0, n_coarse = 0, n_dots = 0, n_integral = 0;
  for (int w = 1; w <= max_w; ++w) {
    const int bh = std::min(max_h, static_cast<int>(max_area_px2 / w));
    if (bh < 1) break;
    const auto sz = [](long a, long b) { return static_cast<std::size_t>(a) * static_cast<std::size_t>(b); };
    const int kx = (w - 1) / 2 + 1, ky = (bh - 1) / 2 + 1;
    const int hw = kx - 1 + hs, hh = ky - 1 + hs;
    n_pos = std::max(n_pos, sz(w, bh));
    n_rows = std::max(n_rows, sz(2 * hh + 1, hw));
    n_half = std::max(n_half, sz(hw, hh) + 16);
    n_table = std::max(n_table, sz(hw + 1, hh + 1));
    n_coarse = std::max(n_coarse, sz(kx, ky));
    n_dots = std::max(n_dots, static_cast<std::size_t>(kx));
    n_integral = std::max(n_integral, sz(w + 2 * h + 3, bh + 2 * h + 3));
  }
  scores_.reserve(n_pos);
  state_.reserve(n_pos);
  if (options_.two_level) {
    half_rows_.reserve(n_rows);
    half_.reserve(n_half);
    half_sum_.reserve(n_table);
    half_sq_.reserve(n_table);
    coarse_.reserve(n_coarse);
    candidates_.reserve(n_coarse);
    half_dots_.reserve(n_dots);
  } else {
    integral_.reserve(n_integral, true);
  }
}

MatchResult ZnccMatcher::match(const Patch& patch, ImageView image, const SearchEllipse& region, ScoreMemo* memo) {
  RTSLAM_CHECK(patch.size() == options_.patch_size, "ZnccMatcher::match: patch size differs from options.patch_size");
  MatchResult res;
  if (patch.centred_energy() <= 0) return res;  // a uniform template cannot be matched
  const int h = patch.half();
  // Positions: the region's bounding box within the centres whose patch fits the image.
  const Roi box = region.bounding_box().intersect(Roi{h, h, image.width - 2 * h, image.height - 2 * h});
  if (box.empty()) return res;
  const std::size_t n_pos = static_cast<std::size_t>(box.w) * static_cast<std::size_t>(box.h);
  if (scores_.size() < n_pos) {
    scores_.resize(n_pos);
    state_.resize(n_pos);
  }
  std::fill_n(state_.data(), n_pos, kUnset);
  const std::size_t box_w = static_cast<std::size_t>(box.w);
  auto index = [&](int u, int v) { return static_cast<std::size_t>(v - box.y) * box_w + (u - box.x); };
  auto inside = [&](int u, int v) { return region.contains(u, v); };
  const bool prune = options_.partial_correlation;
  const int step = options_.partial_step_rows;
  const double kNone = -std::numeric_limits<double>::infinity();

  const bool simd = simd_level() != SimdLevel::scalar;
  // Window sums at full resolution: the exhaustive search evaluates every position, so integral images of the region
  // (grown for the sub-pixel neighbours) cost less than summing each window's rows; the two-level climb evaluates a
  // few dozen positions, which sum their own rows. The tables are made when the first window needs them (a memo
  // may hold every score the search asks for).
  const IntegralImages* table = nullptr;
  // Full-resolution score at (u, v) (with_pruning = false: always complete).
  auto full_score = [&](int u, int v, bool with_pruning, double floor, double* sc) {
    if (!options_.two_level && table == nullptr) {
      integral_.compute(image, Roi{box.x - h - 1, box.y - h - 1, box.w + 2 * h + 2, box.h + 2 * h + 2}, true);
      table = &integral_;
    }
    const int x0 = u - h, y0 = v - h;
    const Window w{image.row(y0) + x0, image.stride, x0, y0, table};
#if defined(__x86_64__)
    if (simd && x0 + patch.padded_stride() <= image.width) {  // the padded reads stay inside the image rows
      return patch.padded_stride() == 16 ? zncc_window<Sse2Kernel<1>>(patch, w, with_pruning, step, floor, sc)
                                         : zncc_window<Sse2Kernel<2>>(patch, w, with_pruning, step, floor, sc);
    }
#endif
    return zncc_window<ScalarKernel>(patch, w, with_pruning, step, floor, sc);
  };
  // The score of a search position if it may reach `floor`, kNone if it is known to be below `floor`. Each position
  // remembers its exact score, or the floor it was abandoned against, so nothing is computed twice and pruning
  // never changes a decision.
  auto score_at = [&](int u, int v, double floor) {
    const std::size_t i = index(u, v);
    if (state_[i] == kExact) return scores_[i];
    double known = 0.0;
    bool known_exact = false;
    if (memo != nullptr && memo->lookup(u, v, known, known_exact)) {
      if (known_exact) {
        state_[i] = kExact;
        scores_[i] = known;
        return known;
      }
      if (known <= floor) {  // score < remembered floor <= floor
        state_[i] = kBelow;
        scores_[i] = known;
        return kNone;
      }
    }
    if (state_[i] == kBelow && scores_[i] <= floor) return kNone;  // score < recorded floor <= floor
    ++res.n_evaluated;
    double sc = 0.0;
    if (!full_score(u, v, prune, floor, &sc)) {
      ++res.n_pruned;
      state_[i] = kBelow;
      scores_[i] = floor;
      if (memo != nullptr) memo->remember(u, v, floor, false);
      return kNone;
    }
    state_[i] = kExact;
    scores_[i] = sc;
    if (memo != nullptr) memo->remember(u, v, sc, true);
    return sc;
  };

  double best = kNone;
  int bu = -1, bv = -1;
  if (!options_.two_level) {
    const double th = options_.threshold;
    for (int v = box.y; v < box.y + box.h; ++v) {
      for (int u = box.x; u < box.x + box.w; ++u) {
        if (!inside(u, v)) continue;
        const double sc = score_at(u, v, std::max(th, best));
        if (sc > best) {
          best = sc;
          bu = u;
          bv = v;
        }
      }
    }
  } else {
    // 1. Half resolution. The reduced image holds [1 2 1] x [1 2 1] sums centred on the pixels
    // (box.x - h + 1 + 2 i, box.y - h + 1 + 2 j); at coarse position (box.x + 2 cx, box.y + 2 cy) the reduced
    // template (centred on the odd template pixels) lies exactly on reduced pixels (cx .. cx + hs - 1, cy ..).
    const int hs = patch.half_size();
    const int kx = (box.w - 1) / 2 + 1, ky = (box.h - 1) / 2 + 1;
    const int hw = kx - 1 + hs, hh = ky - 1 + hs;
    const int ox = box.x - h, oy = box.y - h;
    const int n_rows = 2 * hh + 1;  // full-resolution rows oy .. oy + 2 hh
    half_rows_.resize(static_cast<std::size_t>(n_rows) * static_cast<std::size_t>(hw));
    for (int r = 0; r < n_rows; ++r)
      reduce_row(image.row(oy + r) + ox, hw, half_rows_.data() + static_cast<std::size_t>(r) * hw, simd);
    // Rows are contiguous and the buffer ends with padding, so padded template reads stay inside it.
    const std::size_t n_half = static_cast<std::size_t>(hw) * static_cast<std::size_t>(hh);
    if (half_.size() < n_half + 16) half_.resize(n_half + 16);
    std::fill_n(half_.data() + n_half, 16, std::int16_t{0});
    for (int j = 0; j < hh; ++j) {
      const std::uint16_t* r0 = half_rows_.data() + static_cast<std::size_t>(2 * j) * hw;
      const std::uint16_t* r1 = r0 + hw;
      const std::uint16_t* r2 = r1 + hw;
      std::int16_t* dst = half_.data() + static_cast<std::size_t>(j) * hw;
      for (int i = 0; i < hw; ++i) dst[i] = static_cast<std::int16_t>(r0[i] + 2 * r1[i] + r2[i]);
    }
    const int ts = hw + 1;
    const std::size_t n_table = static_cast<std::size_t>(ts) * static_cast<std::size_t>(hh + 1);
    if (half_sum_.size() < n_table) {
      half_sum_.resize(n_table);
      half_sq_.resize(n_table);
    }
    std::fill_n(half_sum_.data(), ts, 0u);
    std::fill_n(half_sq_.data(), ts, 0u);
    for (int j = 0; j < hh; ++j) {
      std::uint32_t* S = half_sum_.data() + static_cast<std::size_t>(j + 1) * ts;
      std::uint32_t* Q = half_sq_.data() + static_cast<std::size_t>(j + 1) * ts;
      S[0] = Q[0] = 0;
      half_table_row(half_.data() + static_cast<std::size_t>(j) * hw, hw, S - ts, S, Q - ts, Q, simd);
    }
    // Coarse scores (kNone: outside the region or abandoned below the floor of its time).
    const std::size_t n_coarse = static_cast<std::size_t>(kx) * static_cast<std::size_t>(ky);
    coarse_.resize(n_coarse);
    const double coarse_th = options_.threshold - options_.coarse_margin;
    const double spread = options_.coarse_candidates_spread;
    const std::int64_t nh = static_cast<std::int64_t>(hs) * hs;
    const std::int64_t half_sum_a = patch.half_sum();
    const double energy_a = static_cast<double>(patch.half_energy());
    double coarse_best = kNone;
    // No bounded partial correlation here: with 7-row templates the bounds cost more than the rows they skip. A
    // position below the current floor max(coarse_th, best - spread) is discarded without its square root when
    // num² < floor² Ea Eb (1 - 1e-9) shows it; otherwise its score is computed and compared exactly.
    if (half_dots_.size() < static_cast<std::size_t>(kx)) half_dots_.resize(static_cast<std::size_t>(kx));
    for (int cy = 0; cy < ky; ++cy) {
      half_dots(patch.half_data(), hs, patch.half_stride(), half_.data() + static_cast<std::size_t>(cy) * hw, hw, kx,
                half_dots_.data(), simd);
      for (int cx = 0; cx < kx; ++cx) {
        double& out = coarse_[static_cast<std::size_t>(cy) * kx + cx];
        out = kNone;
        if (patch.half_energy() <= 0 || !inside(box.x + 2 * cx, box.y + 2 * cy)) continue;
        ++res.n_evaluated;
        // Window sums from the modular tables (exact: see the kernels).
        const std::uint32_t* s0 = half_sum_.data() + static_cast<std::size_t>(cy) * ts + cx;
        const std::uint32_t* s1 = s0 + static_cast<std::ptrdiff_t>(hs) * ts;
        const std::uint32_t* q0 = half_sq_.data() + static_cast<std::size_t>(cy) * ts + cx;
        const std::uint32_t* q1 = q0 + static_cast<std::ptrdiff_t>(hs) * ts;
        const std::int64_t sb = static_cast<std::uint32_t>(s1[hs] - s1[0] - s0[hs] + s0[0]);
        const std::int64_t sbb = static_cast<std::uint32_t>(q1[hs] - q1[0] - q0[hs] + q0[0]);
        const std::int64_t energy_b = nh * sbb - sb * sb;
        const double floor = std::max(coarse_th, coarse_best - spread);
        double sc = 0.0;
        if (energy_b > 0) {
          const std::int64_t sab = half_dots_[static_cast<std::size_t>(cx)];
          const double num = static_cast<double>(nh * sab - half_sum_a * sb);
          const double den2 = energy_a * static_cast<double>(energy_b);
          if (floor > 0.0 && num * std::abs(num) < floor * floor * den2 * (1.0 - 1e-9)) continue;
          sc = num / std::sqrt(den2);
        }
        if (!(sc >= floor)) continue;
        out = sc;
        coarse_best = std::max(coarse_best, sc);
      }
    }
    // Candidates: coarse local maxima (8-neighbourhood, first of equals) scoring >= max(coarse_th, best - spread).
    // Every coarse score >= that level is exact; abandoned ones were below it, so pruning cannot change this set.
    candidates_.clear();
    const double level = std::max(coarse_th, coarse_best - spread);
    for (int cy = 0; cy < ky; ++cy) {
      for (int cx = 0; cx < kx; ++cx) {
        const double c = coarse_[static_cast<std::size_t>(cy) * kx + cx];
        if (!(c >= level)) continue;
        bool is_max = true;
        for (int dy = -1; dy <= 1 && is_max; ++dy)
          for (int dx = -1; dx <= 1 && is_max; ++dx) {
            const int x = cx + dx, y = cy + dy;
            if ((dx == 0 && dy == 0) || x < 0 || y < 0 || x >= kx || y >= ky) continue;
            const double o = coarse_[static_cast<std::size_t>(y) * kx + x];
            const bool earlier = dy < 0 || (dy == 0 && dx < 0);
            if (o > c || (earlier && o == c)) is_max = false;
          }
        if (is_max) candidates_.push_back({c, box.x + 2 * cx, box.y + 2 * cy});
      }
    }
    // Best first, ties in the raster order they were found in (what a stable sort gives, without its buffer).
    std::sort(candidates_.begin(), candidates_.end(), [](const Candidate& a, const Candidate& b) {
      if (a.score != b.score) return a.score > b.score;
      return a.v < b.v || (a.v == b.v && a.u < b.u);
    });
    // 2. Full resolution: a hill climb through 8-neighbourhoods from each candidate; the best end point wins
    // (first maximum in candidate order).
    for (const Candidate& cand : candidates_) {
      int cu = cand.u, cv = cand.v;
      double cur = score_at(cu, cv, kNone);
      while (true) {
        double step_best = cur;
        int nu = -1, nv = -1;
        const int rad = options_.climb_radius;
        for (int dv = -rad; dv <= rad; ++dv) {
          for (int du = -rad; du <= rad; ++du) {
            const int u = cu + du, v = cv + dv;
            if ((du == 0 && dv == 0) || !box.contains(u, v) || !inside(u, v)) continue;
            const double sc = score_at(u, v, step_best);
            if (sc > step_best) {
              step_best = sc;
              nu = u;
              nv = v;
            }
          }
        }
        if (nu < 0) break;
        cur = step_best;
        cu = nu;
        cv = nv;
      }
      if (cur > best) {
        best = cur;
        bu = cu;
        bv = cv;
      }
    }
  }
  if (bu < 0 || best < options_.threshold) return res;  // no match: counters only
  res.found = true;
  res.u_px = bu;
  res.v_px = bv;
  res.score = best;

  // Sub-pixel refinement on the 3x3 neighbourhood (exact scores; neighbours whose patch leaves the image are
  // skipped).
  double S[3][3] = {};
  bool have[3][3] = {};
  bool all = true;
  for (int dv = -1; dv <= 1; ++dv) {
    for (int du = -1; du <= 1; ++du) {
      const int u = bu + du, v = bv + dv;
      const bool fits = u - h >= 0 && v - h >= 0 && u + h < image.width && v + h < image.height;
      have[dv + 1][du + 1] = fits;
      all = all && fits;
      if (!fits) continue;
      double sc = 0.0;
      bool known_exact = false;
      if (box.contains(u, v) && state_[index(u, v)] == kExact) {
        sc = scores_[index(u, v)];
      } else if (!(memo != nullptr && memo->lookup(u, v, sc, known_exact) && known_exact)) {
        full_score(u, v, false, 0.0, &sc);
        if (memo != nullptr) memo->remember(u, v, sc, true);
      }
      S[dv + 1][du + 1] = sc;
    }
  }
  double ou = 0.0, ov = 0.0;
  bool fitted = false;
  if (all) {
    const double gx = 0.5 * (S[1][2] - S[1][0]);
    const double gy = 0.5 * (S[2][1] - S[0][1]);
    const double hxx = S[1][2] - 2.0 * S[1][1] + S[1][0];
    const double hyy = S[2][1] - 2.0 * S[1][1] + S[0][1];
    const double hxy = 0.25 * (S[2][2] - S[0][2] - S[2][0] + S[0][0]);
    const double det = hxx * hyy - hxy * hxy;
    if (hxx < 0.0 && det > 0.0) {
      ou = -(hyy * gx - hxy * gy) / det;
      ov = -(hxx * gy - hxy * gx) / det;
      fitted = std::abs(ou) <= 0.5 && std::abs(ov) <= 0.5;
    }
  }
  if (!fitted) {
    ou = (have[1][0] && have[1][2]) ? parabola_offset(S[1][0], S[1][1], S[1][2]) : 0.0;
    ov = (have[0][1] && have[2][1]) ? parabola_offset(S[0][1], S[1][1], S[2][1]) : 0.0;
  }
  res.u = bu + ou;
  res.v = bv + ov;
  return res;
}

}  // namespace rtslam::vision
