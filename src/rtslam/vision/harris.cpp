#include "rtslam/vision/harris.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <fmt/format.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace rtslam::vision {

void HarrisOptions::validate() const {
  const std::string where = "harris options";
  require_bound(window_size >= 3 && window_size <= 181 && window_size % 2 == 1, where, "window_size", window_size,
                "odd and in [3, 181]");
  require_bound(k > 0.0 && k < 0.25, where, "k", k, "in (0, 0.25)");
  require_bound(harris_threshold >= 0.0, where, "harris_threshold", harris_threshold, ">= 0");
  require_bound(min_eigen_threshold >= 0.0, where, "min_eigen_threshold", min_eigen_threshold, ">= 0");
  require_bound(edge_ratio >= 1.0, where, "edge_ratio", edge_ratio, ">= 1");
  require_bound(border_px >= 0, where, "border_px", border_px, ">= 0");
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
  o.validate();
  return o;
}

HarrisDetector::HarrisDetector(HarrisOptions options) : options_(options) { options_.validate(); }

double HarrisDetector::response(double a, double b, double c) const {
  if (options_.response == HarrisResponse::harris) {
    const double tr = a + b;
    return a * b - c * c - options_.k * tr * tr;
  }
  const double half_diff = 0.5 * (a - b);
  return 0.5 * (a + b) - std::sqrt(half_diff * half_diff + c * c);
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

// Dx², Dy², DxDy of one row (mid[-1] and mid[w] must exist). The outputs never alias the inputs (restrict lets the
// compiler vectorize despite the 8-bit reads).
void gradient_products(const std::uint8_t* __restrict up, const std::uint8_t* __restrict mid,
                       const std::uint8_t* __restrict down, int w, std::uint32_t* __restrict pxx,
                       std::uint32_t* __restrict pyy, std::uint32_t* __restrict pxy) {
  for (int x = 0; x < w; ++x) {
    const int dx = static_cast<int>(mid[x + 1]) - static_cast<int>(mid[x - 1]);
    const int dy = static_cast<int>(down[x]) - static_cast<int>(up[x]);
    pxx[x] = static_cast<std::uint32_t>(dx * dx);
    pyy[x] = static_cast<std::uint32_t>(dy * dy);
    pxy[x] = static_cast<std::uint32_t>(dx * dy);
  }
}

// One row of a modular integral table: cur[x + 1] = prev[x + 1] + Σ_{i<=x} vals[i] (mod 2^32); cur[0] = 0.
void prefix_row(const std::uint32_t* vals, int w, const std::uint32_t* prev, std::uint32_t* cur) {
  cur[0] = 0;
  int x = 0;
  std::uint32_t run = 0;
#if defined(__SSE2__)
  __m128i carry = _mm_setzero_si128();
  for (; x + 4 <= w; x += 4) {
    __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(vals + x));
    v = _mm_add_epi32(v, _mm_slli_si128(v, 4));
    v = _mm_add_epi32(v, _mm_slli_si128(v, 8));
    v = _mm_add_epi32(v, carry);
    carry = _mm_shuffle_epi32(v, _MM_SHUFFLE(3, 3, 3, 3));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(cur + x + 1),
                     _mm_add_epi32(v, _mm_loadu_si128(reinterpret_cast<const __m128i*>(prev + x + 1))));
  }
  run = static_cast<std::uint32_t>(_mm_cvtsi128_si32(carry));
#endif
  for (; x < w; ++x) {
    run += vals[x];
    cur[x + 1] = prev[x + 1] + run;
  }
}

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

// Quadratic peak offset along one axis from three samples; 0 if the samples are not concave.
double parabola_offset(double rm, double r0, double rp) {
  const double curv = rm - 2.0 * r0 + rp;
  if (!(curv < 0.0)) return 0.0;
  return std::clamp(0.5 * (rm - rp) / curv, -0.5, 0.5);
}

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
  const int ts = gw + 1;  // table stride
  const std::size_t n_plane = static_cast<std::size_t>(ts) * static_cast<std::size_t>(gh + 1);
  if (table_.size() < 3 * n_plane + 3 * static_cast<std::size_t>(gw)) table_.resize(3 * n_plane + 3 * static_cast<std::size_t>(gw));
  std::uint32_t* Txx = table_.data();
  std::uint32_t* Tyy = Txx + n_plane;
  std::uint32_t* Txy = Tyy + n_plane;
  std::uint32_t* pxx = Txy + n_plane;  // products of the current row
  std::uint32_t* pyy = pxx + gw;
  std::uint32_t* pxy = pyy + gw;
  std::fill_n(Txx, ts, 0u);
  std::fill_n(Tyy, ts, 0u);
  std::fill_n(Txy, ts, 0u);
  for (int y = 0; y < gh; ++y) {
    const std::uint8_t* up = image.row(gv0 + y - 1) + gu0;
    const std::uint8_t* mid = image.row(gv0 + y) + gu0;
    const std::uint8_t* down = image.row(gv0 + y + 1) + gu0;
    gradient_products(up, mid, down, gw, pxx, pyy, pxy);
    const std::size_t prev = static_cast<std::size_t>(y) * ts, cur = prev + ts;
    prefix_row(pxx, gw, Txx + prev, Txx + cur);
    prefix_row(pyy, gw, Tyy + prev, Tyy + cur);
    prefix_row(pxy, gw, Txy + prev, Txy + cur);
  }

  // Responses over E (branch-free, vectorizable), then the best candidate of C in raster order (first maximum);
  // the edge test runs only when a candidate would become the best.
  const std::size_t n_resp = static_cast<std::size_t>(ew) * static_cast<std::size_t>(eh);
  if (resp_.size() < n_resp) resp_.resize(n_resp);
  const int ws = options_.window_size;
  const double scale = 1.0 / (4.0 * ws * ws);  // D = 2 g, and the mean over the window's n = ws² pixels
  const double k = options_.k;
  const bool harris = options_.response == HarrisResponse::harris;
  // Window of centre (u, v): G columns [u - hw - gu0, + ws), rows [v - hw - gv0, + ws).
  auto window_sums = [&](int u, int v, double* a, double* b, double* c) {
    const std::size_t i00 = static_cast<std::size_t>(v - hw - gv0) * ts + static_cast<std::size_t>(u - hw - gu0);
    const std::size_t i01 = i00 + ws, i10 = i00 + static_cast<std::size_t>(ws) * ts, i11 = i10 + ws;
    *a = static_cast<std::int32_t>(Txx[i11] - Txx[i10] - Txx[i01] + Txx[i00]) * scale;
    *b = static_cast<std::int32_t>(Tyy[i11] - Tyy[i10] - Tyy[i01] + Tyy[i00]) * scale;
    *c = static_cast<std::int32_t>(Txy[i11] - Txy[i10] - Txy[i01] + Txy[i00]) * scale;
  };
  for (int ey = 0; ey < eh; ++ey) {
    const int v = ev0 + ey;
    const std::size_t r0 = static_cast<std::size_t>(v - hw - gv0) * ts + static_cast<std::size_t>(eu0 - hw - gu0);
    const std::size_t r1 = r0 + static_cast<std::size_t>(ws) * ts;
    const std::uint32_t *xx0 = Txx + r0, *xx1 = Txx + r1, *yy0 = Tyy + r0, *yy1 = Tyy + r1;
    const std::uint32_t *xy0 = Txy + r0, *xy1 = Txy + r1;
    double* out = resp_.data() + static_cast<std::size_t>(ey) * ew;
    if (harris) {
      for (int ex = 0; ex < ew; ++ex) {
        const double a = static_cast<std::int32_t>(xx1[ex + ws] - xx1[ex] - xx0[ex + ws] + xx0[ex]) * scale;
        const double b = static_cast<std::int32_t>(yy1[ex + ws] - yy1[ex] - yy0[ex + ws] + yy0[ex]) * scale;
        const double c = static_cast<std::int32_t>(xy1[ex + ws] - xy1[ex] - xy0[ex + ws] + xy0[ex]) * scale;
        const double tr = a + b;
        out[ex] = a * b - c * c - k * tr * tr;
      }
    } else {
      for (int ex = 0; ex < ew; ++ex) {
        const double a = static_cast<std::int32_t>(xx1[ex + ws] - xx1[ex] - xx0[ex + ws] + xx0[ex]) * scale;
        const double b = static_cast<std::int32_t>(yy1[ex + ws] - yy1[ex] - yy0[ex + ws] + yy0[ex]) * scale;
        const double c = static_cast<std::int32_t>(xy1[ex + ws] - xy1[ex] - xy0[ex + ws] + xy0[ex]) * scale;
        const double half_diff = 0.5 * (a - b);
        out[ex] = 0.5 * (a + b) - std::sqrt(half_diff * half_diff + c * c);
      }
    }
  }
  const double threshold = options_.threshold();
  double best = -std::numeric_limits<double>::infinity();
  int best_u = -1, best_v = -1;
  for (int v = cv0; v <= cv1; ++v) {
    const double* row = resp_.data() + static_cast<std::size_t>(v - ev0) * ew - eu0;
    for (int u = cu0; u <= cu1; ++u) {
      const double r = row[u];
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
  auto R = [&](int u, int v) { return resp_[static_cast<std::size_t>(v - ev0) * ew + (u - eu0)]; };
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
