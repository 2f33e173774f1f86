#include "rtslam/vision/zncc.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/LU>

#if defined(__SSE2__)
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

void ZnccOptions::validate() const {
  const std::string where = "zncc options";
  require_bound(threshold >= -1.0 && threshold <= 1.0, where, "threshold", threshold, "in [-1, 1]");
  require_bound(patch_size >= 5 && patch_size <= 31 && patch_size % 2 == 1, where, "patch_size", patch_size,
                "odd and in [5, 31]");
  require_bound(coarse_margin >= 0.0, where, "coarse_margin", coarse_margin, ">= 0");
  require_bound(coarse_candidates_spread >= 0.0, where, "coarse_candidates_spread", coarse_candidates_spread, ">= 0");
  require_bound(climb_radius >= 1 && climb_radius <= 3, where, "climb_radius", climb_radius, "in [1, 3]");
  require_bound(partial_step_rows >= 1, where, "partial_step_rows", partial_step_rows, ">= 1");
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
  o.validate();
  return o;
}

// ---------------------------------------------------------------------------------------------------------------
// Matcher

ZnccMatcher::ZnccMatcher(ZnccOptions options) : options_(options) { options_.validate(); }

namespace {

constexpr double kBoundMargin = 1e-12;  // covers the rounding of the bound and of the score (~1e-15)

// A square template of either resolution with its precomputed sums; rows are int16, zero-padded to `stride`.
struct TemplateView {
  const std::int16_t* data;
  int size;
  int stride;  // a multiple of 16 (full resolution) or 8 (half resolution)
  std::int64_t sum;
  std::int64_t energy;  // n Σa² - (Σa)²
  const Patch* patch;
  bool half;
  std::int64_t suffix_sum(int r) const { return half ? patch->half_suffix_sum(r) : patch->suffix_sum(r); }
  std::int64_t suffix_sq(int r) const { return half ? patch->half_suffix_sq(r) : patch->suffix_sq(r); }
};

// Dot products of 16 (8-bit image) or 8 (int16 half-resolution image) entries. Products fit int32: 255 * 255 at full
// resolution, 4080 * 4080 at half resolution; a row sums at most 32 such terms (patch <= 31). SSE2 (every x86-64)
// when available, plain C++ otherwise.
#if defined(__SSE2__)
inline std::int32_t hsum_epi32(__m128i v) {
  v = _mm_add_epi32(v, _mm_shuffle_epi32(v, _MM_SHUFFLE(1, 0, 3, 2)));
  v = _mm_add_epi32(v, _mm_shuffle_epi32(v, _MM_SHUFFLE(2, 3, 0, 1)));
  return _mm_cvtsi128_si32(v);
}
inline std::int32_t dot16(const std::int16_t* a, const std::uint8_t* b) {
  const __m128i vb = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b));
  const __m128i zero = _mm_setzero_si128();
  const __m128i lo = _mm_madd_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a)), _mm_unpacklo_epi8(vb, zero));
  const __m128i hi =
      _mm_madd_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a + 8)), _mm_unpackhi_epi8(vb, zero));
  return hsum_epi32(_mm_add_epi32(lo, hi));
}
inline std::int32_t dot8(const std::int16_t* a, const std::int16_t* b) {
  return hsum_epi32(_mm_madd_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a)),
                                   _mm_loadu_si128(reinterpret_cast<const __m128i*>(b))));
}
#else
inline std::int32_t dot16(const std::int16_t* a, const std::uint8_t* b) {
  std::int32_t acc = 0;
  for (int i = 0; i < 16; ++i) acc += static_cast<std::int32_t>(a[i]) * static_cast<std::int32_t>(b[i]);
  return acc;
}
inline std::int32_t dot8(const std::int16_t* a, const std::int16_t* b) {
  std::int32_t acc = 0;
  for (int i = 0; i < 8; ++i) acc += static_cast<std::int32_t>(a[i]) * static_cast<std::int32_t>(b[i]);
  return acc;
}
#endif

// Dot of a template row with an image row: over the padded length when `wide` (reading past the window is then
// allowed: the extra template entries are zero), else over the exact size.
inline std::int32_t dot_row(const TemplateView& t, const std::int16_t* a, const std::uint8_t* b, bool wide) {
  std::int32_t acc = 0;
  if (wide) {
    for (int k = 0; k < t.stride; k += 16) acc += dot16(a + k, b + k);
    return acc;
  }
  for (int i = 0; i < t.size; ++i) acc += static_cast<std::int32_t>(a[i]) * static_cast<std::int32_t>(b[i]);
  return acc;
}
inline std::int32_t dot_row(const TemplateView& t, const std::int16_t* a, const std::int16_t* b, bool /*wide*/) {
  std::int32_t acc = 0;
  for (int k = 0; k < t.stride; k += 8) acc += dot8(a + k, b + k);
  return acc;
}

struct WindowSums {
  std::int64_t sum;
  std::int64_t sq;
};

// ZNCC of template t against the window whose top-left pixel is b (row stride b_stride). window(r0, nr) returns the
// sums of the window rows [r0, r0 + nr). With prune, abandons (returns false) when the bound on the score falls
// strictly below floor (minus the rounding margin).
template <class PB, class Window>
bool zncc_window(const TemplateView& t, const PB* b, std::ptrdiff_t b_stride, bool wide, const Window& window,
                 bool prune, int step, double floor, double* score) {
  const int s = t.size;
  const std::int64_t n = static_cast<std::int64_t>(s) * s;
  const WindowSums all = window(0, s);
  const std::int64_t energy_b = n * all.sq - all.sum * all.sum;
  if (energy_b <= 0) {
    *score = 0.0;
    return true;
  }
  const double inv_den = 1.0 / std::sqrt(static_cast<double>(t.energy) * static_cast<double>(energy_b));
  const double sa_sb = static_cast<double>(t.sum * all.sum);
  const double dn = static_cast<double>(n);
  std::int64_t sab = 0;
  for (int r = 0; r < s; ++r) {
    sab += dot_row(t, t.data + static_cast<std::ptrdiff_t>(r) * t.stride, b + r * b_stride, wide);
    const int done = r + 1;
    if (prune && done % step == 0 && done < s) {
      // Bound of the remaining rows [done, s), m pixels: Cauchy-Schwarz on the centred rows plus the mean term.
      const std::int64_t m = static_cast<std::int64_t>(s - done) * s;
      const std::int64_t sa_r = t.suffix_sum(done);
      const std::int64_t saa_r = t.suffix_sq(done);
      const WindowSums rest_b = window(done, s - done);
      const double ea_r = static_cast<double>(m * saa_r - sa_r * sa_r);
      const double eb_r = static_cast<double>(m * rest_b.sq - rest_b.sum * rest_b.sum);
      const double rest = (std::sqrt(ea_r * eb_r) + static_cast<double>(sa_r * rest_b.sum)) / static_cast<double>(m);
      const double bound = (dn * (static_cast<double>(sab) + rest) - sa_sb) * inv_den;
      if (bound < floor - kBoundMargin) return false;
    }
  }
  *score = static_cast<double>(n * sab - t.sum * all.sum) * inv_den;
  return true;
}

double parabola_offset(double rm, double r0, double rp) {
  const double curv = rm - 2.0 * r0 + rp;
  return curv < 0.0 ? std::clamp(0.5 * (rm - rp) / curv, -0.5, 0.5) : 0.0;
}

}  // namespace

MatchResult ZnccMatcher::match(const Patch& patch, ImageView image, const SearchEllipse& region) {
  RTSLAM_CHECK(patch.size() == options_.patch_size, "ZnccMatcher::match: patch size differs from options.patch_size");
  MatchResult res;
  if (patch.centred_energy() <= 0) return res;  // a uniform template cannot be matched
  const int s = patch.size();
  const int h = patch.half();
  // Positions: the region's bounding box within the centres whose patch fits the image.
  const Roi box = region.bounding_box().intersect(Roi{h, h, image.width - 2 * h, image.height - 2 * h});
  if (box.empty()) return res;
  // Integral images over the box grown by the patch half-size plus one (the sub-pixel fit may read neighbours).
  integral_.compute(image, Roi{box.x - h - 1, box.y - h - 1, box.w + 2 * h + 2, box.h + 2 * h + 2}, true);
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

  const TemplateView full{patch.padded_data(), s, patch.padded_stride(), patch.sum(), patch.centred_energy(), &patch,
                          false};
  // Full-resolution score at (u, v) (with_pruning = false: always complete).
  auto full_score = [&](int u, int v, bool with_pruning, double floor, double* sc) {
    const int x0 = u - h, y0 = v - h;
    auto window = [&](int r0, int nr) {
      return WindowSums{static_cast<std::int64_t>(integral_.sum(x0, y0 + r0, s, nr)),
                        static_cast<std::int64_t>(integral_.sum_sq(x0, y0 + r0, s, nr))};
    };
    const bool wide = x0 + full.stride <= image.width;  // the padded reads stay inside the image rows
    return zncc_window(full, image.row(y0) + x0, image.stride, wide, window, with_pruning, step, floor, sc);
  };
  // The score of a search position if it may reach `floor`, kNone if it is known to be below `floor`. Each position
  // remembers its exact score, or the floor it was abandoned against, so nothing is computed twice and pruning
  // never changes a decision.
  auto score_at = [&](int u, int v, double floor) {
    const std::size_t i = index(u, v);
    if (state_[i] == kExact) return scores_[i];
    if (state_[i] == kBelow && scores_[i] <= floor) return kNone;  // score < recorded floor <= floor
    ++res.n_evaluated;
    double sc = 0.0;
    if (!full_score(u, v, prune, floor, &sc)) {
      ++res.n_pruned;
      state_[i] = kBelow;
      scores_[i] = floor;
      return kNone;
    }
    state_[i] = kExact;
    scores_[i] = sc;
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
    for (int r = 0; r < n_rows; ++r) {
      const std::uint8_t* src = image.row(oy + r) + ox;
      std::uint16_t* dst = half_rows_.data() + static_cast<std::size_t>(r) * hw;
      for (int i = 0; i < hw; ++i)
        dst[i] = static_cast<std::uint16_t>(src[2 * i] + 2 * src[2 * i + 1] + src[2 * i + 2]);
    }
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
    half_sum_.resize(n_table);
    half_sq_.resize(n_table);
    std::fill_n(half_sum_.data(), ts, 0);
    std::fill_n(half_sq_.data(), ts, 0);
    for (int j = 0; j < hh; ++j) {
      std::int64_t rs = 0, rq = 0;
      const std::int16_t* src = half_.data() + static_cast<std::size_t>(j) * hw;
      std::int64_t* S = half_sum_.data() + static_cast<std::size_t>(j + 1) * ts;
      std::int64_t* Q = half_sq_.data() + static_cast<std::size_t>(j + 1) * ts;
      const std::int64_t* Sp = S - ts;
      const std::int64_t* Qp = Q - ts;
      S[0] = Q[0] = 0;
      for (int i = 0; i < hw; ++i) {
        rs += src[i];
        rq += static_cast<std::int64_t>(src[i]) * src[i];
        S[i + 1] = Sp[i + 1] + rs;
        Q[i + 1] = Qp[i + 1] + rq;
      }
    }
    const TemplateView coarse{patch.half_data(), hs, patch.half_stride(), patch.half_sum(), patch.half_energy(),
                              &patch, true};
    // Coarse scores (kNone: outside the region or abandoned below the floor of its time).
    const std::size_t n_coarse = static_cast<std::size_t>(kx) * static_cast<std::size_t>(ky);
    coarse_.resize(n_coarse);
    const double coarse_th = options_.threshold - options_.coarse_margin;
    const double spread = options_.coarse_candidates_spread;
    const std::int64_t nh = static_cast<std::int64_t>(hs) * hs;
    const double energy_a = static_cast<double>(coarse.energy);
    double coarse_best = kNone;
    // No bounded partial correlation here: with 7-row templates the bounds cost more than the rows they skip. A
    // position below the current floor max(coarse_th, best - spread) is discarded without its square root when
    // num² < floor² Ea Eb (1 - 1e-9) shows it; otherwise its score is computed and compared exactly.
    for (int cy = 0; cy < ky; ++cy) {
      for (int cx = 0; cx < kx; ++cx) {
        double& out = coarse_[static_cast<std::size_t>(cy) * kx + cx];
        out = kNone;
        if (coarse.energy <= 0 || !inside(box.x + 2 * cx, box.y + 2 * cy)) continue;
        ++res.n_evaluated;
        const std::int64_t* s0 = half_sum_.data() + static_cast<std::size_t>(cy) * ts + cx;
        const std::int64_t* s1 = s0 + static_cast<std::ptrdiff_t>(hs) * ts;
        const std::int64_t* q0 = half_sq_.data() + static_cast<std::size_t>(cy) * ts + cx;
        const std::int64_t* q1 = q0 + static_cast<std::ptrdiff_t>(hs) * ts;
        const std::int64_t sb = s1[hs] - s1[0] - s0[hs] + s0[0];
        const std::int64_t sbb = q1[hs] - q1[0] - q0[hs] + q0[0];
        const std::int64_t energy_b = nh * sbb - sb * sb;
        const double floor = std::max(coarse_th, coarse_best - spread);
        double sc = 0.0;
        if (energy_b > 0) {
          const std::int16_t* b = half_.data() + static_cast<std::size_t>(cy) * hw + cx;
          std::int64_t sab = 0;
          for (int r = 0; r < hs; ++r)
            sab += dot_row(coarse, coarse.data + static_cast<std::ptrdiff_t>(r) * coarse.stride, b + r * hw, true);
          const double num = static_cast<double>(nh * sab - coarse.sum * sb);
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
    std::stable_sort(candidates_.begin(), candidates_.end(),
                     [](const Candidate& a, const Candidate& b) { return a.score > b.score; });
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
      if (box.contains(u, v) && state_[index(u, v)] == kExact) {
        sc = scores_[index(u, v)];
      } else {
        full_score(u, v, false, 0.0, &sc);
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
