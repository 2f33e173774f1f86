#pragma once
// Register prefix sums shared by the SSE2/AVX2 kernels of the integral images and Harris (x86-64 only; internal to
// src/rtslam/vision). AVX2 functions carry the target attribute: they are called only from AVX2 kernels chosen at
// run time (simd.hpp).
#if defined(__x86_64__)
#include <immintrin.h>

#define RTSLAM_AVX2 __attribute__((target("avx2")))

namespace rtslam::vision::detail {

/// Prefix sums of 4 uint32 lanes.
inline __m128i prefix4_epu32(__m128i v) {
  v = _mm_add_epi32(v, _mm_slli_si128(v, 4));
  return _mm_add_epi32(v, _mm_slli_si128(v, 8));
}
/// The last uint32 lane broadcast.
inline __m128i last_epu32(__m128i v) { return _mm_shuffle_epi32(v, _MM_SHUFFLE(3, 3, 3, 3)); }

/// Prefix sums of 8 uint32 lanes: within each 128-bit half, then the low half's total added to the high half.
RTSLAM_AVX2 inline __m256i prefix8_epu32(__m256i v) {
  v = _mm256_add_epi32(v, _mm256_slli_si256(v, 4));
  v = _mm256_add_epi32(v, _mm256_slli_si256(v, 8));
  const __m256i t = _mm256_shuffle_epi32(v, _MM_SHUFFLE(3, 3, 3, 3));
  return _mm256_add_epi32(v, _mm256_permute2x128_si256(t, t, 0x08));
}
/// The last uint32 lane broadcast.
RTSLAM_AVX2 inline __m256i last_epu32(__m256i v) { return _mm256_permutevar8x32_epi32(v, _mm256_set1_epi32(7)); }

}  // namespace rtslam::vision::detail

#endif  // __x86_64__
