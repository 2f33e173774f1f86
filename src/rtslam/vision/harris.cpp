#include "rtslam/vision/harris.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <fmt/format.h>

#include "rtslam/vision/peak.hpp"
#include "rtslam/vision/simd.hpp"

#if defined(__x86_64__)
#include <immintrin.h>

#include "rtslam/vision/simd_prefix.hpp"
#endif

namespace rtslam::vision {

namespace {

// The response of a normalized structure matrix [a c; c b]: Harris det - k tr², or λmin. Every SIMD level evaluates
// these same double expressions, so all levels return identical responses.
inline double response_of(double a, double b, double c, double k, bool harris) {
  if (harris) {
    const double tr = a + b;
    return a * b - c * c - k * tr * tr;
  }
  const double half_diff = 0.5 * (a - b);
  return 0.5 * (a + b) - std::sqrt(half_diff * half_diff + c * c);
}

}  // namespace

void HarrisOptions::validate(const std::string& where) const {
  require_bound(window_size >= 3 && window_size <= 181 && window_size % 2 == 1, where, "window_size", window_size,
                "odd and in [3, 181]");
  require_bound(k > 0.0 && k < 0.25, where, "k", k, "in (0, 0.25)");
  // Responses of 8-bit images: the Harris response of a window of gradients up to 255 stays far below 1e12.
  require_bound(harris_threshold >= 0.0 && harris_threshold <= 1e12, where, "harris_threshold", harris_threshold,
                "in [0, 1e12]");
  require_bound(min_eigen_threshold >= 0.0 && min_eigen_threshold <= 1e12, where, "min_eigen_threshold",
                min_eigen_threshold, "in [0, 1e12]");
  require_bound(edge_ratio >= 1.0 && edge_ratio <= 1e6, where, "edge_ratio", edge_ratio, "in [1, 1e6]");
  require_bound(border_px >= 0 && border_px <= 1000, where, "border_px", border_px, "in [0, 1000] px");
}

HarrisOptions HarrisOptions::from_yaml(YamlMap& map) {
  HarrisOptions o;
  map.get("window_size", o.window_size);
  map.get("k", o.k);
  if (map.has("response")) {
    std::string r;
    map.get("response", r);
    if (r == "harris") {
      o.response = HarrisResponse::harris;
    } else if (r == "min_eigen") {
      o.response = HarrisResponse::min_eigen;
    } else {
      throw ConfigError(fmt::format("{}: response = '{}' must be 'harris' or 'min_eigen'", map.where(), r));
    }
  }
  map.get("harris_threshold", o.harris_threshold);
  map.get("min_eigen_threshold", o.min_eigen_threshold);
  map.get("edge_ratio", o.edge_ratio);
  map.get("border_px", o.border_px);
  if (map.has("subpixel")) {
    std::string sp;
    map.get("subpixel", sp);
    if (sp == "quadratic") {
      o.subpixel = HarrisSubpixel::quadratic;
    } else if (sp == "edge_lines") {
      o.subpixel = HarrisSubpixel::edge_lines;
    } else {
      throw ConfigError(fmt::format("{}: subpixel = '{}' must be 'quadratic' or 'edge_lines'", map.where(), sp));
    }
  }
  map.finish();
  o.validate(map.where());
  return o;
}

YAML::Node HarrisOptions::to_yaml() const {
  YAML::Node n;
  n["window_size"] = window_size;
  n["k"] = k;
  n["response"] = response == HarrisResponse::harris ? "harris" : "min_eigen";
  n["harris_threshold"] = harris_threshold;
  n["min_eigen_threshold"] = min_eigen_threshold;
  n["edge_ratio"] = edge_ratio;
  n["border_px"] = border_px;
  n["subpixel"] = subpixel == HarrisSubpixel::quadratic ? "quadratic" : "edge_lines";
  return n;
}

HarrisDetector::HarrisDetector(HarrisOptions options) : options_(options) { options_.validate(); }

double HarrisDetector::response(double a, double b, double c) const {
  return response_of(a, b, c, options_.k, options_.response == HarrisResponse::harris);
}

bool HarrisDetector::passes_edge_test(double a, double b, double c) const {
  const double half_diff = 0.5 * (a - b);
  const double root = std::sqrt(half_diff * half_diff + c * c);
  const double l_min = 0.5 * (a + b) - root;
  const double l_max = 0.5 * (a + b) + root;
  return l_min > 0.0 && l_max <= options_.edge_ratio * l_min;
}

namespace {

// Clips [lo, hi] (inclusive) to [a, b].
void clip(int& lo, int& hi, int a, int b) {
  lo = std::max(lo, a);
  hi = std::min(hi, b);
}

// Integral tables of Dx², Dy², DxDy over the gradient area, one row at a time. A row kernel gets the image rows
// above, at and below the table row (up, mid, down at the area's first column; mid[-1] and mid[w] must exist) and
// writes the table row cur[x + 1] = cur[x + 1 - ts] + Σ_{i<=x} product[i] for x in [0, w) of the three planes,
// which lie `plane` entries apart (the caller sets cur[0]). Accumulation is modulo 2^32 (see best_corner).
using TableRow = void (*)(const std::uint8_t* up, const std::uint8_t* mid, const std::uint8_t* down, int w,
                          std::uint32_t* cur, std::ptrdiff_t ts, std::ptrdiff_t plane);

// Plain C++, also the tail of the SIMD kernels: columns [x, w) from the row sums of columns [0, x).
void table_row_from(const std::uint8_t* up, const std::uint8_t* mid, const std::uint8_t* down, int x, int w,
                    std::uint32_t* cur, std::ptrdiff_t ts, std::ptrdiff_t plane, std::uint32_t rxx, std::uint32_t ryy,
                    std::uint32_t rxy) {
  std::uint32_t* cxx = cur;
  std::uint32_t* cyy = cur + plane;
  std::uint32_t* cxy = cur + 2 * plane;
  for (; x < w; ++x) {
    const int dx = static_cast<int>(mid[x + 1]) - static_cast<int>(mid[x - 1]);
    const int dy = static_cast<int>(down[x]) - static_cast<int>(up[x]);
    rxx += static_cast<std::uint32_t>(dx * dx);
    ryy += static_cast<std::uint32_t>(dy * dy);
    rxy += static_cast<std::uint32_t>(dx * dy);
    cxx[x + 1] = cxx[x + 1 - ts] + rxx;
    cyy[x + 1] = cyy[x + 1 - ts] + ryy;
    cxy[x + 1] = cxy[x + 1 - ts] + rxy;
  }
}

void table_row_scalar(const std::uint8_t* up, const std::uint8_t* mid, const std::uint8_t* down, int w,
                      std::uint32_t* cur, std::ptrdiff_t ts, std::ptrdiff_t plane) {
  table_row_from(up, mid, down, 0, w, cur, ts, plane, 0, 0, 0);
}

// Responses of a run of n window positions in one row: out[i] for the window whose top-left table entries are
// xx[i], xx[i] + plane (Dy²) and xx[i] + 2 plane (DxDy), `down` = ws * ts entries above its bottom-left ones.
// Returns the largest response. Every level evaluates the expressions of response_of, in the same order.
struct ResponseRun {
  const std::uint32_t* xx;
  std::ptrdiff_t plane;
  std::ptrdiff_t down;
  int ws;
  int n;
  double scale;  // 1 / (4 ws²): D = 2 g, and the mean over the window
  double k;
  bool harris;
};
using ResponseRow = double (*)(const ResponseRun& run, double* out);

// Window sum of one plane at table entry p (modular difference, exact: see best_corner).
inline double window_value(const std::uint32_t* p, std::ptrdiff_t down, int ws, double scale) {
  return static_cast<std::int32_t>(p[down + ws] - p[down] - p[ws] + p[0]) * scale;
}

double response_row_from(const ResponseRun& r, int i, double best, double* out) {
  for (; i < r.n; ++i) {
    const std::uint32_t* p = r.xx + i;
    const double a = window_value(p, r.down, r.ws, r.scale);
    const double b = window_value(p + r.plane, r.down, r.ws, r.scale);
    const double c = window_value(p + 2 * r.plane, r.down, r.ws, r.scale);
    out[i] = response_of(a, b, c, r.k, r.harris);
    best = std::max(best, out[i]);
  }
  return best;
}

double response_row_scalar(const ResponseRun& r, double* out) {
  return response_row_from(r, 0, -std::numeric_limits<double>::infinity(), out);
}

// The largest window sum of Dx² + Dy² (the unnormalized trace) over the run. It bounds every response of the run
// (see best_corner); it fits uint32 (2 * 181² * 65025 < 2^32).
using TraceRow = std::uint32_t (*)(const ResponseRun& run);

// Window sum of Dx² + Dy² at table entry p (modular differences; the sum is exact).
inline std::uint32_t trace_value(const std::uint32_t* p, std::ptrdiff_t plane, std::ptrdiff_t down, int ws) {
  const std::uint32_t* q = p + plane;
  return (p[down + ws] - p[down] - p[ws] + p[0]) + (q[down + ws] - q[down] - q[ws] + q[0]);
}

std::uint32_t trace_row_from(const ResponseRun& r, int i, std::uint32_t best) {
  for (; i < r.n; ++i) best = std::max(best, trace_value(r.xx + i, r.plane, r.down, r.ws));
  return best;
}

std::uint32_t trace_row_scalar(const ResponseRun& r) { return trace_row_from(r, 0, 0); }

#if defined(__x86_64__)

using detail::last_epu32;
using detail::prefix4_epu32;
using detail::prefix8_epu32;

// SSE2 kernels. Products are exact in int32 (|D| <= 255). Prefix sums are built in registers without the running
// row sum, which is added afterwards, so consecutive steps depend on each other through one add per plane. Products
// enter as pair sums: pmaddwd of the int16 derivatives gives d[2i] e[2i] + d[2i + 1] e[2i + 1], whose prefixes are
// the row prefixes at the odd pixels; an even pixel's prefix is its odd neighbour's minus that neighbour's product.

// One plane, 8 pixels: d, e are the int16 derivatives (product d e), d_odd is d with its even lanes zeroed.
// cur[0..8) = cur[-ts..8-ts) + carry + prefix; the carry becomes the row sum so far.
inline void products8_store(__m128i d, __m128i d_odd, __m128i e, std::uint32_t* cur, std::ptrdiff_t ts,
                            __m128i* carry) {
  const __m128i odd = _mm_add_epi32(prefix4_epu32(_mm_madd_epi16(d, e)), *carry);
  const __m128i even = _mm_sub_epi32(odd, _mm_madd_epi16(d_odd, e));
  *carry = last_epu32(odd);
  _mm_storeu_si128(
      reinterpret_cast<__m128i*>(cur),
      _mm_add_epi32(_mm_unpacklo_epi32(even, odd), _mm_loadu_si128(reinterpret_cast<const __m128i*>(cur - ts))));
  _mm_storeu_si128(
      reinterpret_cast<__m128i*>(cur + 4),
      _mm_add_epi32(_mm_unpackhi_epi32(even, odd), _mm_loadu_si128(reinterpret_cast<const __m128i*>(cur + 4 - ts))));
}

// Columns [x, x + 8) of a table row (the SSE2 step, also the 8-pixel tail of the AVX2 kernel).
inline void table_step8(const std::uint8_t* up, const std::uint8_t* mid, const std::uint8_t* down, int x,
                        std::uint32_t* cur, std::ptrdiff_t ts, std::ptrdiff_t plane, __m128i carry[3]) {
  const __m128i zero = _mm_setzero_si128();
  const __m128i odd_mask = _mm_set1_epi32(static_cast<int>(0xFFFF0000u));
  auto load8 = [&](const std::uint8_t* p) {
    return _mm_unpacklo_epi8(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(p)), zero);
  };
  const __m128i dx = _mm_sub_epi16(load8(mid + x + 1), load8(mid + x - 1));
  const __m128i dy = _mm_sub_epi16(load8(down + x), load8(up + x));
  const __m128i dx_odd = _mm_and_si128(dx, odd_mask), dy_odd = _mm_and_si128(dy, odd_mask);
  products8_store(dx, dx_odd, dx, cur + x + 1, ts, &carry[0]);
  products8_store(dy, dy_odd, dy, cur + plane + x + 1, ts, &carry[1]);
  products8_store(dx, dx_odd, dy, cur + 2 * plane + x + 1, ts, &carry[2]);
}

// Columns [x, w) after the SIMD steps: one more 8-pixel step ending at w, which rewrites the columns before x with
// the same values (its carries are read back from the row written so far), or plain C++ in rows narrower than 8.
inline void table_row_tail(const std::uint8_t* up, const std::uint8_t* mid, const std::uint8_t* down, int x, int w,
                           std::uint32_t* cur, std::ptrdiff_t ts, std::ptrdiff_t plane, __m128i carry[3]) {
  if (x == w) return;
  if (w < 8) {
    table_row_from(up, mid, down, x, w, cur, ts, plane, static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry[0])),
                   static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry[1])),
                   static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry[2])));
    return;
  }
  x = w - 8;
  for (int k = 0; k < 3; ++k) {  // the row sum of columns [0, x): this row's entry minus the one above
    const std::uint32_t* e = cur + k * plane + x;
    carry[k] = _mm_set1_epi32(static_cast<int>(e[0] - e[-ts]));
  }
  table_step8(up, mid, down, x, cur, ts, plane, carry);
}

void table_row_sse2(const std::uint8_t* up, const std::uint8_t* mid, const std::uint8_t* down, int w,
                    std::uint32_t* cur, std::ptrdiff_t ts, std::ptrdiff_t plane) {
  __m128i carry[3] = {_mm_setzero_si128(), _mm_setzero_si128(), _mm_setzero_si128()};
  int x = 0;
  for (; x + 8 <= w; x += 8) table_step8(up, mid, down, x, cur, ts, plane, carry);
  table_row_tail(up, mid, down, x, w, cur, ts, plane, carry);
}

// Window sums of 4 consecutive positions of one plane (int32 lanes).
inline __m128i window4(const std::uint32_t* p, std::ptrdiff_t down, int ws) {
  auto ld = [](const std::uint32_t* q) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(q)); };
  return _mm_add_epi32(_mm_sub_epi32(_mm_sub_epi32(ld(p + down + ws), ld(p + down)), ld(p + ws)), ld(p));
}

// 2 int32 lanes (0-1, or 2-3 when high) as doubles, times scale.
inline __m128d scaled_pd(__m128i v, int high, __m128d scale) {
  return _mm_mul_pd(_mm_cvtepi32_pd(high ? _mm_shuffle_epi32(v, _MM_SHUFFLE(3, 2, 3, 2)) : v), scale);
}

double response_row_sse2(const ResponseRun& r, double* out) {
  const __m128d scale = _mm_set1_pd(r.scale), k = _mm_set1_pd(r.k), half = _mm_set1_pd(0.5);
  __m128d best = _mm_set1_pd(-std::numeric_limits<double>::infinity());
  int i = 0;
  for (; i + 4 <= r.n; i += 4) {
    const std::uint32_t* p = r.xx + i;
    const __m128i A = window4(p, r.down, r.ws);
    const __m128i B = window4(p + r.plane, r.down, r.ws);
    const __m128i C = window4(p + 2 * r.plane, r.down, r.ws);
    for (int h = 0; h < 2; ++h) {
      const __m128d a = scaled_pd(A, h, scale), b = scaled_pd(B, h, scale), c = scaled_pd(C, h, scale);
      __m128d resp;
      if (r.harris) {
        const __m128d tr = _mm_add_pd(a, b);
        resp = _mm_sub_pd(_mm_sub_pd(_mm_mul_pd(a, b), _mm_mul_pd(c, c)), _mm_mul_pd(_mm_mul_pd(k, tr), tr));
      } else {
        const __m128d hd = _mm_mul_pd(half, _mm_sub_pd(a, b));
        resp = _mm_sub_pd(_mm_mul_pd(half, _mm_add_pd(a, b)),
                          _mm_sqrt_pd(_mm_add_pd(_mm_mul_pd(hd, hd), _mm_mul_pd(c, c))));
      }
      _mm_storeu_pd(out + i + 2 * h, resp);
      best = _mm_max_pd(best, resp);
    }
  }
  double lanes[2];
  _mm_storeu_pd(lanes, best);
  return response_row_from(r, i, std::max(lanes[0], lanes[1]), out);
}

std::uint32_t trace_row_sse2(const ResponseRun& r) {
  // Unsigned maximum through a signed compare of the values offset by 2^31 (SSE2 has no pmaxud).
  const __m128i bias = _mm_set1_epi32(static_cast<int>(0x80000000u));
  __m128i best = bias;  // 0, offset
  int i = 0;
  for (; i + 4 <= r.n; i += 4) {
    const std::uint32_t* p = r.xx + i;
    const __m128i t = _mm_xor_si128(_mm_add_epi32(window4(p, r.down, r.ws), window4(p + r.plane, r.down, r.ws)), bias);
    const __m128i greater = _mm_cmpgt_epi32(t, best);
    best = _mm_or_si128(_mm_and_si128(greater, t), _mm_andnot_si128(greater, best));
  }
  alignas(16) std::uint32_t lanes[4];
  _mm_store_si128(reinterpret_cast<__m128i*>(lanes), _mm_xor_si128(best, bias));
  return trace_row_from(r, i, std::max(std::max(lanes[0], lanes[1]), std::max(lanes[2], lanes[3])));
}

// AVX2 kernels: the same computations, 8 int32 or 4 double lanes.


// One plane, 16 pixels (int16 lanes), as products8_store.
RTSLAM_AVX2 inline void products16_store(__m256i d, __m256i d_odd, __m256i e, std::uint32_t* cur, std::ptrdiff_t ts,
                                         __m256i* carry) {
  const __m256i odd = _mm256_add_epi32(prefix8_epu32(_mm256_madd_epi16(d, e)), *carry);
  const __m256i even = _mm256_sub_epi32(odd, _mm256_madd_epi16(d_odd, e));
  *carry = _mm256_permutevar8x32_epi32(odd, _mm256_set1_epi32(7));
  const __m256i lo = _mm256_unpacklo_epi32(even, odd);  // pixels 0-3 | 8-11
  const __m256i hi = _mm256_unpackhi_epi32(even, odd);  // pixels 4-7 | 12-15
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(cur),
                      _mm256_add_epi32(_mm256_permute2x128_si256(lo, hi, 0x20),
                                       _mm256_loadu_si256(reinterpret_cast<const __m256i*>(cur - ts))));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(cur + 8),
                      _mm256_add_epi32(_mm256_permute2x128_si256(lo, hi, 0x31),
                                       _mm256_loadu_si256(reinterpret_cast<const __m256i*>(cur + 8 - ts))));
}

// 16 pixels as int16 lanes.
RTSLAM_AVX2 inline __m256i load16_epi16(const std::uint8_t* p) {
  return _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
}

RTSLAM_AVX2 void table_row_avx2(const std::uint8_t* up, const std::uint8_t* mid, const std::uint8_t* down, int w,
                                std::uint32_t* cur, std::ptrdiff_t ts, std::ptrdiff_t plane) {
  const __m256i odd_mask = _mm256_set1_epi32(static_cast<int>(0xFFFF0000u));
  __m256i carry[3] = {_mm256_setzero_si256(), _mm256_setzero_si256(), _mm256_setzero_si256()};
  int x = 0;
  for (; x + 16 <= w; x += 16) {
    const __m256i dx = _mm256_sub_epi16(load16_epi16(mid + x + 1), load16_epi16(mid + x - 1));
    const __m256i dy = _mm256_sub_epi16(load16_epi16(down + x), load16_epi16(up + x));
    const __m256i dx_odd = _mm256_and_si256(dx, odd_mask), dy_odd = _mm256_and_si256(dy, odd_mask);
    products16_store(dx, dx_odd, dx, cur + x + 1, ts, &carry[0]);
    products16_store(dy, dy_odd, dy, cur + plane + x + 1, ts, &carry[1]);
    products16_store(dx, dx_odd, dy, cur + 2 * plane + x + 1, ts, &carry[2]);
  }
  __m128i carry4[3] = {_mm256_castsi256_si128(carry[0]), _mm256_castsi256_si128(carry[1]),
                       _mm256_castsi256_si128(carry[2])};  // the row sums, in every lane
  _mm256_zeroupper();
  if (x + 8 <= w) {
    table_step8(up, mid, down, x, cur, ts, plane, carry4);
    x += 8;
  }
  table_row_tail(up, mid, down, x, w, cur, ts, plane, carry4);
}

RTSLAM_AVX2 inline __m256i load8_epu32(const std::uint32_t* p) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
}

// Window sums of 8 consecutive positions of one plane (int32 lanes).
RTSLAM_AVX2 inline __m256i window8(const std::uint32_t* p, std::ptrdiff_t down, int ws) {
  return _mm256_add_epi32(
      _mm256_sub_epi32(_mm256_sub_epi32(load8_epu32(p + down + ws), load8_epu32(p + down)), load8_epu32(p + ws)),
      load8_epu32(p));
}

// 4 int32 lanes (0-3, or 4-7 when high) as doubles, times scale.
RTSLAM_AVX2 inline __m256d scaled_pd(__m256i v, int high, __m256d scale) {
  return _mm256_mul_pd(_mm256_cvtepi32_pd(high ? _mm256_extracti128_si256(v, 1) : _mm256_castsi256_si128(v)), scale);
}

RTSLAM_AVX2 double response_row_avx2(const ResponseRun& r, double* out) {
  const __m256d scale = _mm256_set1_pd(r.scale), k = _mm256_set1_pd(r.k), half = _mm256_set1_pd(0.5);
  __m256d best = _mm256_set1_pd(-std::numeric_limits<double>::infinity());
  int i = 0;
  for (; i + 8 <= r.n; i += 8) {
    const std::uint32_t* p = r.xx + i;
    const __m256i A = window8(p, r.down, r.ws);
    const __m256i B = window8(p + r.plane, r.down, r.ws);
    const __m256i C = window8(p + 2 * r.plane, r.down, r.ws);
    for (int h = 0; h < 2; ++h) {
      const __m256d a = scaled_pd(A, h, scale), b = scaled_pd(B, h, scale), c = scaled_pd(C, h, scale);
      __m256d resp;
      if (r.harris) {
        const __m256d tr = _mm256_add_pd(a, b);
        resp = _mm256_sub_pd(_mm256_sub_pd(_mm256_mul_pd(a, b), _mm256_mul_pd(c, c)),
                             _mm256_mul_pd(_mm256_mul_pd(k, tr), tr));
      } else {
        const __m256d hd = _mm256_mul_pd(half, _mm256_sub_pd(a, b));
        resp = _mm256_sub_pd(_mm256_mul_pd(half, _mm256_add_pd(a, b)),
                             _mm256_sqrt_pd(_mm256_add_pd(_mm256_mul_pd(hd, hd), _mm256_mul_pd(c, c))));
      }
      _mm256_storeu_pd(out + i + 4 * h, resp);
      best = _mm256_max_pd(best, resp);
    }
  }
  double lanes[4];
  _mm256_storeu_pd(lanes, best);
  _mm256_zeroupper();
  return response_row_from(r, i, std::max(std::max(lanes[0], lanes[1]), std::max(lanes[2], lanes[3])), out);
}

RTSLAM_AVX2 std::uint32_t trace_row_avx2(const ResponseRun& r) {
  __m256i best = _mm256_setzero_si256();
  int i = 0;
  for (; i + 8 <= r.n; i += 8) {
    const std::uint32_t* p = r.xx + i;
    best = _mm256_max_epu32(best, _mm256_add_epi32(window8(p, r.down, r.ws), window8(p + r.plane, r.down, r.ws)));
  }
  alignas(32) std::uint32_t lanes[8];
  _mm256_store_si256(reinterpret_cast<__m256i*>(lanes), best);
  _mm256_zeroupper();  // before plain SSE code (see simd.hpp)
  return trace_row_from(r, i, *std::max_element(lanes, lanes + 8));
}

#endif  // __x86_64__

// Förstner-style refinement: the point q closest, in the least-squares sense, to the lines through every pixel x_i
// of a (2r + 1)² window orthogonal to its gradient g_i: q = (Σ g gᵀ)⁻¹ Σ g gᵀ x_i, with the [-1 0 1] gradients.
// Re-centred once on round(q). False if the window leaves the image, the system is singular or q moves more than
// 3 px from the starting pixel (the box-window response peaks up to ~2 px inside an L-corner).
bool edge_lines_refine(ImageView image, int u0, int v0, int r, double* u, double* v) {
  int cu = u0, cv = v0;
  for (int iter = 0; iter < 2; ++iter) {
    if (cu - r - 1 < 0 || cv - r - 1 < 0 || cu + r + 1 >= image.width || cv + r + 1 >= image.height) return false;
    double a = 0, b = 0, c = 0, bx = 0, by = 0;
    for (int y = -r; y <= r; ++y) {
      const std::uint8_t* up = image.row(cv + y - 1) + cu;
      const std::uint8_t* mid = image.row(cv + y) + cu;
      const std::uint8_t* down = image.row(cv + y + 1) + cu;
      for (int x = -r; x <= r; ++x) {
        const double gx = static_cast<double>(mid[x + 1]) - mid[x - 1];
        const double gy = static_cast<double>(down[x]) - up[x];
        a += gx * gx;
        b += gy * gy;
        c += gx * gy;
        bx += gx * gx * x + gx * gy * y;
        by += gx * gy * x + gy * gy * y;
      }
    }
    const double det = a * b - c * c;
    if (!(det > 1e-9 * (a + b) * (a + b))) return false;
    const double qx = (b * bx - c * by) / det, qy = (a * by - c * bx) / det;
    *u = cu + qx;
    *v = cv + qy;
    if (std::abs(*u - u0) > 3.0 || std::abs(*v - v0) > 3.0) return false;
    const int nu = static_cast<int>(std::lround(*u)), nv = static_cast<int>(std::lround(*v));
    if (nu == cu && nv == cv) return true;
    cu = nu;
    cv = nv;
  }
  return true;
}

constexpr int kFitMargin = 3;  // responses computed beyond the candidates, for the 5x5 fit and one re-centring

}  // namespace

std::optional<Corner> HarrisDetector::best_corner(ImageView image, const Roi& roi) {
  const int hw = options_.window_size / 2;
  const int W = image.width;
  const int H = image.height;
  // Window centres whose window and derivatives fit in the image.
  const int valid_u0 = hw + 1, valid_u1 = W - 2 - hw;
  const int valid_v0 = hw + 1, valid_v1 = H - 2 - hw;
  // Candidate area C (inclusive bounds).
  int cu0 = roi.x, cu1 = roi.x + roi.w - 1, cv0 = roi.y, cv1 = roi.y + roi.h - 1;
  clip(cu0, cu1, std::max(options_.border_px, valid_u0), std::min(W - 1 - options_.border_px, valid_u1));
  clip(cv0, cv1, std::max(options_.border_px, valid_v0), std::min(H - 1 - options_.border_px, valid_v1));
  if (cu0 > cu1 || cv0 > cv1) return std::nullopt;
  // Response area E = C grown by kFitMargin pixels (for the sub-pixel fit), still valid.
  const int eu0 = std::max(cu0 - kFitMargin, valid_u0), eu1 = std::min(cu1 + kFitMargin, valid_u1);
  const int ev0 = std::max(cv0 - kFitMargin, valid_v0), ev1 = std::min(cv1 + kFitMargin, valid_v1);
  const int ew = eu1 - eu0 + 1, eh = ev1 - ev0 + 1;
  // Gradient area G = E grown by the window half-width; inside [1, W-2] x [1, H-2] by construction.
  const int gu0 = eu0 - hw, gv0 = ev0 - hw;
  const int gw = ew + 2 * hw, gh = eh + 2 * hw;

  // Integral images of Dx², Dy², DxDy over G (three planar tables). They are accumulated in uint32 modulo 2^32
  // (unsigned wrap-around is well defined): a window sum, at most window_size² * 65025 in magnitude (< 2^31 for
  // windows up to 181x181), is recovered exactly by the same modular four-corner difference, whatever the ROI size.
  const std::ptrdiff_t ts = gw + 1;  // table stride
  const std::ptrdiff_t n_plane = ts * (gh + 1);
  if (table_.size() < static_cast<std::size_t>(3 * n_plane)) table_.resize(static_cast<std::size_t>(3 * n_plane));
  std::uint32_t* Txx = table_.data();
  std::fill_n(Txx, ts, 0u);
  std::fill_n(Txx + n_plane, ts, 0u);
  std::fill_n(Txx + 2 * n_plane, ts, 0u);
  TableRow table_row = table_row_scalar;
  TraceRow trace_row = trace_row_scalar;
  ResponseRow response_row = response_row_scalar;
#if defined(__x86_64__)
  const SimdLevel level = simd_level();
  if (level == SimdLevel::avx2) {
    table_row = table_row_avx2;
    trace_row = trace_row_avx2;
    response_row = response_row_avx2;
  } else if (level == SimdLevel::sse2) {
    table_row = table_row_sse2;
    trace_row = trace_row_sse2;
    response_row = response_row_sse2;
  }
#endif
  for (int y = 0; y < gh; ++y) {
    std::uint32_t* cur = Txx + (y + 1) * ts;
    cur[0] = cur[n_plane] = cur[2 * n_plane] = 0;
    table_row(image.row(gv0 + y - 1) + gu0, image.row(gv0 + y) + gu0, image.row(gv0 + y + 1) + gu0, gw, cur, ts,
              n_plane);
  }

  // Responses of C row by row (vectorized), then the best candidate in raster order (first maximum) among those
  // reaching the threshold and passing the edge test. A row is skipped when a bound shows that none of its responses
  // can be a new best, it is scanned only if its largest response could be, and the edge test runs only for a
  // candidate that would become the best.
  // Bound: with tr = a + b (a, b >= 0), ab <= tr² / 4, so Harris ab - c² - k tr² <= (1/4 - k) tr², and
  // λmin <= tr / 2. The computed responses exceed these by less than 1e-15 tr² (or tr), hence the 1e-12 margins.
  const int ws = options_.window_size;
  const double scale = 1.0 / (4.0 * ws * ws);  // D = 2 g, and the mean over the window's n = ws² pixels
  const bool harris = options_.response == HarrisResponse::harris;
  // Table entry of the top-left corner of the window centred on (u, v): G column u - hw - gu0, row v - hw - gv0.
  auto corner = [&](int u, int v) { return Txx + (v - hw - gv0) * ts + (u - hw - gu0); };
  const std::ptrdiff_t down = ws * ts;
  auto window_sums = [&](int u, int v, double* a, double* b, double* c) {
    const std::uint32_t* p = corner(u, v);
    *a = window_value(p, down, ws, scale);
    *b = window_value(p + n_plane, down, ws, scale);
    *c = window_value(p + 2 * n_plane, down, ws, scale);
  };
  const int cw = cu1 - cu0 + 1;
  if (resp_.size() < static_cast<std::size_t>(cw)) resp_.resize(static_cast<std::size_t>(cw));
  const double threshold = options_.threshold();
  double best = -std::numeric_limits<double>::infinity();
  int best_u = -1, best_v = -1;
  for (int v = cv0; v <= cv1; ++v) {
    const ResponseRun run{corner(cu0, v), n_plane, down, ws, cw, scale, options_.k, harris};
    const double tr_max = trace_row(run) * scale * (1.0 + 1e-12);
    const double bound = harris ? (0.25 - options_.k + 1e-12) * tr_max * tr_max : 0.5 * tr_max;
    if (bound < threshold || bound <= best) continue;
    const double row_max = response_row(run, resp_.data());
    if (!(row_max > best && row_max >= threshold)) continue;
    for (int u = cu0; u <= cu1; ++u) {
      const double r = resp_[static_cast<std::size_t>(u - cu0)];
      if (r > best && r >= threshold) {
        double a, b, c;
        window_sums(u, v, &a, &b, &c);
        if (passes_edge_test(a, b, c)) {
          best = r;
          best_u = u;
          best_v = v;
        }
      }
    }
  }
  if (best_u < 0) return std::nullopt;

  // Sub-pixel: least-squares quadratic fit of the 5x5 responses around a centre pixel p (first the best pixel,
  // then, once, the pixel nearest the fitted vertex), vertex accepted within 1.5 px of p. With the box window the
  // response of a corner is flat-topped over ~2 px, so a 3x3 fit would follow the integer maximum; the 5x5 fit sees
  // the whole hump. Fallbacks: the 3x3 fit, then separable parabolas (clamped to +-0.5 px).
  // Responses of E, computed from the tables on demand (the same expressions as the row kernels).
  auto R = [&](int u, int v) {
    double a, b, c;
    window_sums(u, v, &a, &b, &c);
    return response_of(a, b, c, options_.k, harris);
  };
  auto has = [&](int u, int v, int r) { return u - r >= eu0 && u + r <= eu1 && v - r >= ev0 && v + r <= ev1; };
  // Vertex offset of f = a0 + a1 i + a2 j + a3 i² + a4 ij + a5 j² fitted on i, j in [-r, r] (r = 1 or 2). On the
  // symmetric grid the normal equations decouple: a1 = Σ i f / Σ i², a4 = Σ ij f / Σ i²j², a3 = Σ (i² - m) f /
  // Σ (i² - m)² with m the mean of i².
  auto fit = [&](int pu, int pv, int r, double* ou, double* ov) {
    const double m = r == 1 ? 2.0 / 3.0 : 2.0;
    double s_i = 0, s_j = 0, s_ij = 0, s_ii = 0, s_jj = 0, d_ii = 0, d_ij = 0, d_qq = 0;
    for (int j = -r; j <= r; ++j)
      for (int i = -r; i <= r; ++i) {
        const double f = R(pu + i, pv + j);
        s_i += i * f;
        s_j += j * f;
        s_ij += i * j * f;
        s_ii += (i * i - m) * f;
        s_jj += (j * j - m) * f;
        d_ii += i * i;
        d_ij += i * i * j * j;
        d_qq += (i * i - m) * (i * i - m);
      }
    const double gx = s_i / d_ii, gy = s_j / d_ii;
    const double hxx = 2.0 * s_ii / d_qq, hyy = 2.0 * s_jj / d_qq, hxy = s_ij / d_ij;
    const double det = hxx * hyy - hxy * hxy;
    if (!(hxx < 0.0 && det > 0.0)) return false;
    *ou = -(hyy * gx - hxy * gy) / det;
    *ov = -(hxx * gy - hxy * gx) / det;
    return true;
  };
  Corner c;
  c.u_px = best_u;
  c.v_px = best_v;
  c.score = best;
  double du = 0.0, dv = 0.0;
  bool fitted = false;
  if (has(best_u, best_v, 2) && fit(best_u, best_v, 2, &du, &dv) && std::abs(du) <= 1.5 && std::abs(dv) <= 1.5) {
    fitted = true;
    const int pu = best_u + static_cast<int>(std::lround(du)), pv = best_v + static_cast<int>(std::lround(dv));
    double du2 = 0.0, dv2 = 0.0;
    if ((pu != best_u || pv != best_v) && has(pu, pv, 2) && fit(pu, pv, 2, &du2, &dv2) &&
        std::abs(pu - best_u + du2) <= 1.5 && std::abs(pv - best_v + dv2) <= 1.5) {
      du = pu - best_u + du2;
      dv = pv - best_v + dv2;
    }
  }
  if (!fitted && has(best_u, best_v, 1)) {
    fitted = fit(best_u, best_v, 1, &du, &dv) && std::abs(du) <= 0.5 && std::abs(dv) <= 0.5;
  }
  if (options_.subpixel == HarrisSubpixel::edge_lines) {
    double ru = 0.0, rv = 0.0;
    if (edge_lines_refine(image, best_u, best_v, hw + 3, &ru, &rv)) {
      c.u = ru;
      c.v = rv;
      return c;
    }
  }
  if (!fitted) {
    const bool has_l = best_u - 1 >= eu0, has_r = best_u + 1 <= eu1;
    const bool has_t = best_v - 1 >= ev0, has_b = best_v + 1 <= ev1;
    du = (has_l && has_r) ? parabola_offset(R(best_u - 1, best_v), best, R(best_u + 1, best_v)) : 0.0;
    dv = (has_t && has_b) ? parabola_offset(R(best_u, best_v - 1), best, R(best_u, best_v + 1)) : 0.0;
  }
  c.u = best_u + du;
  c.v = best_v + dv;
  return c;
}

}  // namespace rtslam::vision
