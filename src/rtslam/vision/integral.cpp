#include "rtslam/vision/integral.hpp"

#include <algorithm>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace rtslam::vision {

namespace {

// One row of both tables: s[x + 1] = s_prev[x + 1] + Σ_{i<=x} src[i], q likewise with squares. Row sums of squares
// stay exact in uint32 for rows up to 66051 pixels (65025 * 66051 < 2^32).
void row_both(const std::uint8_t* src, int w, const std::uint32_t* s_prev, std::uint32_t* s, const std::uint64_t* q_prev,
              std::uint64_t* q) {
  int x = 0;
  std::uint32_t row_sum = 0, row_sq = 0;
#if defined(__SSE2__)
  // 8 pixels per step: in-register prefix sums of 4 uint32 lanes plus the running carry.
  const __m128i zero = _mm_setzero_si128();
  __m128i carry_s = _mm_setzero_si128(), carry_q = _mm_setzero_si128();
  auto prefix4 = [](__m128i v) {
    v = _mm_add_epi32(v, _mm_slli_si128(v, 4));
    return _mm_add_epi32(v, _mm_slli_si128(v, 8));
  };
  for (; x + 8 <= w; x += 8) {
    const __m128i p16 = _mm_unpacklo_epi8(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(src + x)), zero);
    const __m128i sq16 = _mm_mullo_epi16(p16, p16);  // <= 65025: exact in uint16
    const __m128i p_lo = _mm_unpacklo_epi16(p16, zero), p_hi = _mm_unpackhi_epi16(p16, zero);
    const __m128i q_lo = _mm_unpacklo_epi16(sq16, zero), q_hi = _mm_unpackhi_epi16(sq16, zero);
    const __m128i s_lo = _mm_add_epi32(prefix4(p_lo), carry_s);
    const __m128i s_hi = _mm_add_epi32(prefix4(p_hi), _mm_shuffle_epi32(s_lo, _MM_SHUFFLE(3, 3, 3, 3)));
    carry_s = _mm_shuffle_epi32(s_hi, _MM_SHUFFLE(3, 3, 3, 3));
    const __m128i r_lo = _mm_add_epi32(prefix4(q_lo), carry_q);
    const __m128i r_hi = _mm_add_epi32(prefix4(q_hi), _mm_shuffle_epi32(r_lo, _MM_SHUFFLE(3, 3, 3, 3)));
    carry_q = _mm_shuffle_epi32(r_hi, _MM_SHUFFLE(3, 3, 3, 3));
    std::uint32_t* sd = s + x + 1;
    const std::uint32_t* sp = s_prev + x + 1;
    _mm_storeu_si128(reinterpret_cast<__m128i*>(sd),
                     _mm_add_epi32(s_lo, _mm_loadu_si128(reinterpret_cast<const __m128i*>(sp))));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(sd + 4),
                     _mm_add_epi32(s_hi, _mm_loadu_si128(reinterpret_cast<const __m128i*>(sp + 4))));
    std::uint64_t* qd = q + x + 1;
    const std::uint64_t* qp = q_prev + x + 1;
    const __m128i parts[4] = {_mm_unpacklo_epi32(r_lo, zero), _mm_unpackhi_epi32(r_lo, zero),
                              _mm_unpacklo_epi32(r_hi, zero), _mm_unpackhi_epi32(r_hi, zero)};
    for (int k = 0; k < 4; ++k)
      _mm_storeu_si128(reinterpret_cast<__m128i*>(qd + 2 * k),
                       _mm_add_epi64(parts[k], _mm_loadu_si128(reinterpret_cast<const __m128i*>(qp + 2 * k))));
  }
  row_sum = static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry_s));
  row_sq = static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry_q));
#endif
  for (; x < w; ++x) {
    const std::uint32_t p = src[x];
    row_sum += p;
    row_sq += p * p;
    s[x + 1] = s_prev[x + 1] + row_sum;
    q[x + 1] = q_prev[x + 1] + row_sq;
  }
}

void row_sum_only(const std::uint8_t* src, int w, const std::uint32_t* s_prev, std::uint32_t* s) {
  int x = 0;
  std::uint32_t row_sum = 0;
#if defined(__SSE2__)
  const __m128i zero = _mm_setzero_si128();
  __m128i carry = _mm_setzero_si128();
  auto prefix4 = [](__m128i v) {
    v = _mm_add_epi32(v, _mm_slli_si128(v, 4));
    return _mm_add_epi32(v, _mm_slli_si128(v, 8));
  };
  for (; x + 8 <= w; x += 8) {
    const __m128i p16 = _mm_unpacklo_epi8(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(src + x)), zero);
    const __m128i s_lo = _mm_add_epi32(prefix4(_mm_unpacklo_epi16(p16, zero)), carry);
    const __m128i s_hi =
        _mm_add_epi32(prefix4(_mm_unpackhi_epi16(p16, zero)), _mm_shuffle_epi32(s_lo, _MM_SHUFFLE(3, 3, 3, 3)));
    carry = _mm_shuffle_epi32(s_hi, _MM_SHUFFLE(3, 3, 3, 3));
    std::uint32_t* sd = s + x + 1;
    const std::uint32_t* sp = s_prev + x + 1;
    _mm_storeu_si128(reinterpret_cast<__m128i*>(sd),
                     _mm_add_epi32(s_lo, _mm_loadu_si128(reinterpret_cast<const __m128i*>(sp))));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(sd + 4),
                     _mm_add_epi32(s_hi, _mm_loadu_si128(reinterpret_cast<const __m128i*>(sp + 4))));
  }
  row_sum = static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry));
#endif
  for (; x < w; ++x) {
    row_sum += src[x];
    s[x + 1] = s_prev[x + 1] + row_sum;
  }
}

}  // namespace

void IntegralImages::compute(ImageView image, Roi roi, bool with_squares) {
  roi_ = roi.intersect(image.rect());
  stride_ = roi_.w + 1;
  has_squares_ = with_squares;
  const std::size_t n = static_cast<std::size_t>(stride_) * static_cast<std::size_t>(roi_.h + 1);
  if (sum_.size() < n) sum_.resize(n);
  if (with_squares && sq_.size() < n) sq_.resize(n);

  std::fill_n(sum_.data(), stride_, 0u);
  if (with_squares) std::fill_n(sq_.data(), stride_, std::uint64_t{0});
  for (int y = 0; y < roi_.h; ++y) {
    const std::uint8_t* src = image.row(roi_.y + y) + roi_.x;
    const std::size_t prev = static_cast<std::size_t>(y) * stride_, cur = prev + stride_;
    sum_[cur] = 0;
    if (with_squares) {
      sq_[cur] = 0;
      row_both(src, roi_.w, sum_.data() + prev, sum_.data() + cur, sq_.data() + prev, sq_.data() + cur);
    } else {
      row_sum_only(src, roi_.w, sum_.data() + prev, sum_.data() + cur);
    }
  }
}

}  // namespace rtslam::vision
