#include "rtslam/vision/integral.hpp"

#include <algorithm>

#include "rtslam/vision/simd.hpp"

#if defined(__x86_64__)
#include <immintrin.h>

#include "rtslam/vision/simd_prefix.hpp"
#endif

namespace rtslam::vision {

namespace {

// One row of the tables: s[x + 1] = s_prev[x + 1] + Σ_{i<=x} src[i] for x in [0, w), q likewise with squares, all
// modulo 2^32 (the caller sets s[0] and q[0]).
using RowBoth = void (*)(const std::uint8_t*, int, const std::uint32_t*, std::uint32_t*, const std::uint32_t*,
                         std::uint32_t*);
using RowSum = void (*)(const std::uint8_t*, int, const std::uint32_t*, std::uint32_t*);

// Plain C++, also the tail of the SIMD kernels: columns [x, w), starting from the row sums of columns [0, x).
void row_both_from(const std::uint8_t* src, int x, int w, std::uint32_t row_sum, std::uint32_t row_sq,
                   const std::uint32_t* s_prev, std::uint32_t* s, const std::uint32_t* q_prev, std::uint32_t* q) {
  for (; x < w; ++x) {
    const std::uint32_t p = src[x];
    row_sum += p;
    row_sq += p * p;
    s[x + 1] = s_prev[x + 1] + row_sum;
    q[x + 1] = q_prev[x + 1] + row_sq;
  }
}

void row_sum_from(const std::uint8_t* src, int x, int w, std::uint32_t row_sum, const std::uint32_t* s_prev,
                  std::uint32_t* s) {
  for (; x < w; ++x) {
    row_sum += src[x];
    s[x + 1] = s_prev[x + 1] + row_sum;
  }
}

void row_both_scalar(const std::uint8_t* src, int w, const std::uint32_t* s_prev, std::uint32_t* s,
                     const std::uint32_t* q_prev, std::uint32_t* q) {
  row_both_from(src, 0, w, 0, 0, s_prev, s, q_prev, q);
}

void row_sum_scalar(const std::uint8_t* src, int w, const std::uint32_t* s_prev, std::uint32_t* s) {
  row_sum_from(src, 0, w, 0, s_prev, s);
}

#if defined(__x86_64__)

using detail::last_epu32;
using detail::prefix4_epu32;
using detail::prefix8_epu32;

// SSE2, 16 pixels per step. Row prefixes are built in registers without the running row sum (the carry), which is
// added afterwards: the only dependency between steps is one add per table.
//  - sums: 16-bit prefixes first (at most 16 * 255), widened to 32 bits;
//  - squares: pmaddwd gives the sums of pixel pairs (2i, 2i + 1), whose prefixes are the row prefixes at the odd
//    pixels; an even pixel's prefix is its odd neighbour's minus that neighbour's square.

// Prefix sums of 8 uint16 lanes (the sums must stay below 2^16).
inline __m128i prefix8_epu16(__m128i v) {
  v = _mm_add_epi16(v, _mm_slli_si128(v, 2));
  v = _mm_add_epi16(v, _mm_slli_si128(v, 4));
  return _mm_add_epi16(v, _mm_slli_si128(v, 8));
}
inline __m128i last_epu16(__m128i v) {
  const __m128i t = _mm_shufflehi_epi16(v, _MM_SHUFFLE(3, 3, 3, 3));
  return _mm_unpackhi_epi64(t, t);
}

// t[0..4) = t_prev[0..4) + v.
inline void store_row4(std::uint32_t* t, const std::uint32_t* t_prev, __m128i v) {
  _mm_storeu_si128(reinterpret_cast<__m128i*>(t),
                   _mm_add_epi32(v, _mm_loadu_si128(reinterpret_cast<const __m128i*>(t_prev))));
}

// The prefix sums of 16 pixels (uint16 lanes p0: pixels 0-7, p1: 8-15) as 4 x 4 uint32 lanes.
inline void prefix16_sums(__m128i p0, __m128i p1, __m128i out[4]) {
  const __m128i zero = _mm_setzero_si128();
  const __m128i c0 = prefix8_epu16(p0);
  const __m128i c1 = _mm_add_epi16(prefix8_epu16(p1), last_epu16(c0));
  out[0] = _mm_unpacklo_epi16(c0, zero);
  out[1] = _mm_unpackhi_epi16(c0, zero);
  out[2] = _mm_unpacklo_epi16(c1, zero);
  out[3] = _mm_unpackhi_epi16(c1, zero);
}

void row_both_sse2(const std::uint8_t* src, int w, const std::uint32_t* s_prev, std::uint32_t* s,
                   const std::uint32_t* q_prev, std::uint32_t* q) {
  const __m128i zero = _mm_setzero_si128();
  const __m128i odd_mask = _mm_set1_epi32(static_cast<int>(0xFFFF0000u));
  __m128i carry_s = zero, carry_q = zero;  // row sums of the columns already done, in every lane
  int x = 0;
  for (; x + 16 <= w; x += 16) {
    const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + x));
    const __m128i p0 = _mm_unpacklo_epi8(b, zero), p1 = _mm_unpackhi_epi8(b, zero);
    __m128i c[4];
    prefix16_sums(p0, p1, c);
    for (int k = 0; k < 4; ++k) store_row4(s + x + 1 + 4 * k, s_prev + x + 1 + 4 * k, _mm_add_epi32(c[k], carry_s));
    carry_s = _mm_add_epi32(carry_s, last_epu32(c[3]));
    const __m128i odd0 = _mm_add_epi32(prefix4_epu32(_mm_madd_epi16(p0, p0)), carry_q);
    const __m128i odd1 = _mm_add_epi32(prefix4_epu32(_mm_madd_epi16(p1, p1)), last_epu32(odd0));
    carry_q = last_epu32(odd1);
    const __m128i even0 = _mm_sub_epi32(odd0, _mm_madd_epi16(_mm_and_si128(p0, odd_mask), p0));
    const __m128i even1 = _mm_sub_epi32(odd1, _mm_madd_epi16(_mm_and_si128(p1, odd_mask), p1));
    store_row4(q + x + 1, q_prev + x + 1, _mm_unpacklo_epi32(even0, odd0));
    store_row4(q + x + 5, q_prev + x + 5, _mm_unpackhi_epi32(even0, odd0));
    store_row4(q + x + 9, q_prev + x + 9, _mm_unpacklo_epi32(even1, odd1));
    store_row4(q + x + 13, q_prev + x + 13, _mm_unpackhi_epi32(even1, odd1));
  }
  row_both_from(src, x, w, static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry_s)),
                static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry_q)), s_prev, s, q_prev, q);
}

void row_sum_sse2(const std::uint8_t* src, int w, const std::uint32_t* s_prev, std::uint32_t* s) {
  const __m128i zero = _mm_setzero_si128();
  __m128i carry = zero;
  int x = 0;
  for (; x + 16 <= w; x += 16) {
    const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + x));
    __m128i c[4];
    prefix16_sums(_mm_unpacklo_epi8(b, zero), _mm_unpackhi_epi8(b, zero), c);
    for (int k = 0; k < 4; ++k) store_row4(s + x + 1 + 4 * k, s_prev + x + 1 + 4 * k, _mm_add_epi32(c[k], carry));
    carry = _mm_add_epi32(carry, last_epu32(c[3]));
  }
  row_sum_from(src, x, w, static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry)), s_prev, s);
}

// AVX2, 16 pixels per step, the same scheme with 8 lanes.

RTSLAM_AVX2 inline void store_row8(std::uint32_t* t, const std::uint32_t* t_prev, __m256i v) {
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(t),
                      _mm256_add_epi32(v, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(t_prev))));
}
// The prefix sums of 16 pixels (uint16 lanes of p) as 2 x 8 uint32 lanes: 16-bit prefixes within each 8-pixel half,
// widened, then the first half's total added to the second.
RTSLAM_AVX2 inline void prefix16_sums(__m256i p, __m256i* c0, __m256i* c1) {
  __m256i c = _mm256_add_epi16(p, _mm256_slli_si256(p, 2));
  c = _mm256_add_epi16(c, _mm256_slli_si256(c, 4));
  c = _mm256_add_epi16(c, _mm256_slli_si256(c, 8));
  *c0 = _mm256_cvtepu16_epi32(_mm256_castsi256_si128(c));
  *c1 = _mm256_add_epi32(_mm256_cvtepu16_epi32(_mm256_extracti128_si256(c, 1)), last_epu32(*c0));
}

RTSLAM_AVX2 void row_both_avx2(const std::uint8_t* src, int w, const std::uint32_t* s_prev, std::uint32_t* s,
                               const std::uint32_t* q_prev, std::uint32_t* q) {
  const __m256i odd_mask = _mm256_set1_epi32(static_cast<int>(0xFFFF0000u));
  __m256i carry_s = _mm256_setzero_si256(), carry_q = _mm256_setzero_si256();
  int x = 0;
  for (; x + 16 <= w; x += 16) {
    const __m256i p = _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(src + x)));
    __m256i c0, c1;
    prefix16_sums(p, &c0, &c1);
    store_row8(s + x + 1, s_prev + x + 1, _mm256_add_epi32(c0, carry_s));
    store_row8(s + x + 9, s_prev + x + 9, _mm256_add_epi32(c1, carry_s));
    carry_s = _mm256_add_epi32(carry_s, last_epu32(c1));
    const __m256i odd = _mm256_add_epi32(prefix8_epu32(_mm256_madd_epi16(p, p)), carry_q);
    const __m256i even = _mm256_sub_epi32(odd, _mm256_madd_epi16(_mm256_and_si256(p, odd_mask), p));
    carry_q = last_epu32(odd);
    const __m256i lo = _mm256_unpacklo_epi32(even, odd);  // pixels 0-3 | 8-11
    const __m256i hi = _mm256_unpackhi_epi32(even, odd);  // pixels 4-7 | 12-15
    store_row8(q + x + 1, q_prev + x + 1, _mm256_permute2x128_si256(lo, hi, 0x20));
    store_row8(q + x + 9, q_prev + x + 9, _mm256_permute2x128_si256(lo, hi, 0x31));
  }
  const auto row_sum = static_cast<std::uint32_t>(_mm256_cvtsi256_si32(carry_s));
  const auto row_sq = static_cast<std::uint32_t>(_mm256_cvtsi256_si32(carry_q));
  _mm256_zeroupper();  // before plain SSE code (see simd.hpp)
  row_both_from(src, x, w, row_sum, row_sq, s_prev, s, q_prev, q);
}

RTSLAM_AVX2 void row_sum_avx2(const std::uint8_t* src, int w, const std::uint32_t* s_prev, std::uint32_t* s) {
  __m256i carry = _mm256_setzero_si256();
  int x = 0;
  for (; x + 16 <= w; x += 16) {
    __m256i c0, c1;
    prefix16_sums(_mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(src + x))), &c0, &c1);
    store_row8(s + x + 1, s_prev + x + 1, _mm256_add_epi32(c0, carry));
    store_row8(s + x + 9, s_prev + x + 9, _mm256_add_epi32(c1, carry));
    carry = _mm256_add_epi32(carry, last_epu32(c1));
  }
  const auto row_sum = static_cast<std::uint32_t>(_mm256_cvtsi256_si32(carry));
  _mm256_zeroupper();
  row_sum_from(src, x, w, row_sum, s_prev, s);
}

#endif  // __x86_64__

}  // namespace

void IntegralImages::reserve(std::size_t n_pixels, bool with_squares) {
  sum_.reserve(n_pixels);
  if (with_squares) sq_.reserve(n_pixels);
}

void IntegralImages::compute(ImageView image, Roi roi, bool with_squares) {
  roi_ = roi.intersect(image.rect());
  stride_ = roi_.w + 1;
  has_squares_ = with_squares;
  const std::size_t n = static_cast<std::size_t>(stride_) * static_cast<std::size_t>(roi_.h + 1);
  if (sum_.size() < n) sum_.resize(n);
  if (with_squares && sq_.size() < n) sq_.resize(n);

  RowBoth row_both = row_both_scalar;
  RowSum row_sum = row_sum_scalar;
#if defined(__x86_64__)
  const SimdLevel level = simd_level();
  if (level == SimdLevel::avx2) {
    row_both = row_both_avx2;
    row_sum = row_sum_avx2;
  } else if (level == SimdLevel::sse2) {
    row_both = row_both_sse2;
    row_sum = row_sum_sse2;
  }
#endif

  std::fill_n(sum_.data(), stride_, 0u);
  if (with_squares) std::fill_n(sq_.data(), stride_, 0u);
  for (int y = 0; y < roi_.h; ++y) {
    const std::uint8_t* src = image.row(roi_.y + y) + roi_.x;
    const std::size_t prev = static_cast<std::size_t>(y) * stride_, cur = prev + stride_;
    sum_[cur] = 0;
    if (with_squares) {
      sq_[cur] = 0;
      row_both(src, roi_.w, sum_.data() + prev, sum_.data() + cur, sq_.data() + prev, sq_.data() + cur);
    } else {
      row_sum(src, roi_.w, sum_.data() + prev, sum_.data() + cur);
    }
  }
}

std::uint64_t IntegralImages::sum_sq_banded(int x, int y, int w, int h) const {
  // Tiles of at most kMaxExactSqPx pixels: bands of whole rows of the rectangle, or pieces of single rows when a row
  // alone is wider. Each tile's modular difference is its exact sum.
  const int tile_w = std::min(w, kMaxExactSqPx);
  const int tile_h = std::max(1, kMaxExactSqPx / tile_w);
  std::uint64_t total = 0;
  for (int ty = y; ty < y + h; ty += tile_h)
    for (int tx = x; tx < x + w; tx += tile_w)
      total += sq_rect(tx, ty, std::min(tile_w, x + w - tx), std::min(tile_h, y + h - ty));
  return total;
}

}  // namespace rtslam::vision
