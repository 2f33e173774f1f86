#include "rtslam/vision/warp.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>

#include "rtslam/vision/simd.hpp"
#include "rtslam/vision/simd_prefix.hpp"

namespace rtslam::vision {

namespace {

Eigen::Matrix3d k_matrix(const PinholeIntrinsics& K) {
  Eigen::Matrix3d k;
  k << K.fx, 0.0, K.cx, 0.0, K.fy, K.cy, 0.0, 0.0, 1.0;
  return k;
}

Eigen::Vector2d project(const PinholeIntrinsics& K, const Eigen::Vector3d& p_C) {
  return {K.fx * p_C.x() / p_C.z() + K.cx, K.fy * p_C.y() / p_C.z() + K.cy};
}

}  // namespace

bool plane_homography(const PinholeIntrinsics& K, const RigidPose& T_WC0, const RigidPose& T_WC1,
                      const Eigen::Vector3d& p_W, Eigen::Matrix3d* H_1_0) {
  const Eigen::Vector3d p_C0 = T_WC0.R.transpose() * (p_W - T_WC0.t);
  const Eigen::Vector3d p_C1 = T_WC1.R.transpose() * (p_W - T_WC1.t);
  if (!(p_C0.z() > 0.0) || !(p_C1.z() > 0.0)) return false;
  const double d0 = p_C0.norm();
  const Eigen::Vector3d n_C0 = p_C0 / d0;
  const Eigen::Matrix3d R_C1C0 = T_WC1.R.transpose() * T_WC0.R;
  const Eigen::Vector3d t_C1C0 = T_WC1.R.transpose() * (T_WC0.t - T_WC1.t);
  const Eigen::Matrix3d k = k_matrix(K);
  Eigen::Matrix3d k_inv = Eigen::Matrix3d::Identity();
  k_inv << 1.0 / K.fx, 0.0, -K.cx / K.fx, 0.0, 1.0 / K.fy, -K.cy / K.fy, 0.0, 0.0, 1.0;
  *H_1_0 = k * (R_C1C0 + t_C1C0 * n_C0.transpose() / d0) * k_inv;
  return true;
}

double sample_bilinear(ImageView image, double u, double v) {
  u = std::clamp(u, 0.0, static_cast<double>(image.width - 1));
  v = std::clamp(v, 0.0, static_cast<double>(image.height - 1));
  const int u0 = std::min(static_cast<int>(u), image.width - 2 < 0 ? 0 : image.width - 2);
  const int v0 = std::min(static_cast<int>(v), image.height - 2 < 0 ? 0 : image.height - 2);
  const int u1 = std::min(u0 + 1, image.width - 1), v1 = std::min(v0 + 1, image.height - 1);
  const double fu = u - u0, fv = v - v0;
  const double top = (1.0 - fu) * image.at(u0, v0) + fu * image.at(u1, v0);
  const double bottom = (1.0 - fu) * image.at(u0, v1) + fu * image.at(u1, v1);
  return (1.0 - fv) * top + fv * bottom;
}

namespace {

/// Output pixel (i, j) -> homogeneous x0 = G (i, j, 1) -> patch coordinates (pu, pv) = A0 x0 + off.
struct PixelMap {
  double G[3][3];
  double A0[2][2];
  double off_u, off_v;
  double max_u, max_v;
};

/// One predicted pixel; false if its ray misses the plane in front of C0. The AVX2 kernel computes the same double
/// operations in the same order (no FMA), so both give the same bytes.
[[gnu::always_inline]] inline bool warp_pixel(const PixelMap& m, ImageView init_patch, int i, int j, std::uint8_t& dst,
                                              int& n_outside) {
  const double xh = m.G[0][0] * i + m.G[0][1] * j + m.G[0][2];
  const double yh = m.G[1][0] * i + m.G[1][1] * j + m.G[1][2];
  const double zh = m.G[2][0] * i + m.G[2][1] * j + m.G[2][2];
  if (!(zh > 0.0)) return false;
  const double x0 = xh / zh, y0 = yh / zh;
  double pu = m.A0[0][0] * x0 + m.A0[0][1] * y0 + m.off_u;
  double pv = m.A0[1][0] * x0 + m.A0[1][1] * y0 + m.off_v;
  if (pu >= 0.0 && pu < m.max_u && pv >= 0.0 && pv < m.max_v) {  // inside: plain bilinear, no clamping
    const int iu = static_cast<int>(pu), iv = static_cast<int>(pv);
    const double fu = pu - iu, fv = pv - iv;
    const std::uint8_t* p0 = init_patch.row(iv) + iu;
    const std::uint8_t* p1 = p0 + init_patch.stride;
    const double top = p0[0] + fu * (p0[1] - p0[0]);
    const double bottom = p1[0] + fu * (p1[1] - p1[0]);
    dst = static_cast<std::uint8_t>(top + fv * (bottom - top) + 0.5);
    return true;
  }
  if (!(pu >= 0.0 && pu <= m.max_u && pv >= 0.0 && pv <= m.max_v)) ++n_outside;
  pu = std::clamp(pu, 0.0, m.max_u);
  pv = std::clamp(pv, 0.0, m.max_v);
  dst = static_cast<std::uint8_t>(sample_bilinear(init_patch, pu, pv) + 0.5);
  return true;
}

bool warp_scalar(const PixelMap& m, ImageView init_patch, MutableImageView out, int& n_outside) {
  for (int j = 0; j < out.height; ++j) {
    std::uint8_t* dst = out.row(j);
    for (int i = 0; i < out.width; ++i) {
      if (!warp_pixel(m, init_patch, i, j, dst[i], n_outside)) return false;
    }
  }
  return true;
}

#if defined(__x86_64__)
/// Four output pixels at a time, in raster order across rows (a 15x15 patch is 56 groups and one pixel). A group
/// with a pixel outside the stored patch's interior is done pixel by pixel, as the scalar kernel does it. The lanes'
/// coordinates and pixels are built in registers: a vector load of four scalar stores would stall on forwarding.
RTSLAM_AVX2 bool warp_avx2(const PixelMap& m, ImageView init_patch, MutableImageView out, int& n_outside) {
  const int w = out.width, total = out.width * out.height;
  const __m256d g00 = _mm256_set1_pd(m.G[0][0]), g01 = _mm256_set1_pd(m.G[0][1]), g02 = _mm256_set1_pd(m.G[0][2]);
  const __m256d g10 = _mm256_set1_pd(m.G[1][0]), g11 = _mm256_set1_pd(m.G[1][1]), g12 = _mm256_set1_pd(m.G[1][2]);
  const __m256d g20 = _mm256_set1_pd(m.G[2][0]), g21 = _mm256_set1_pd(m.G[2][1]), g22 = _mm256_set1_pd(m.G[2][2]);
  const __m256d a00 = _mm256_set1_pd(m.A0[0][0]), a01 = _mm256_set1_pd(m.A0[0][1]);
  const __m256d a10 = _mm256_set1_pd(m.A0[1][0]), a11 = _mm256_set1_pd(m.A0[1][1]);
  const __m256d off_u = _mm256_set1_pd(m.off_u), off_v = _mm256_set1_pd(m.off_v);
  const __m256d max_u = _mm256_set1_pd(m.max_u), max_v = _mm256_set1_pd(m.max_v);
  const __m256d zero = _mm256_setzero_pd(), half = _mm256_set1_pd(0.5), one = _mm256_set1_pd(1.0);
  const __m256d width = _mm256_set1_pd(w), four = _mm256_set1_pd(4.0);
  const __m128i low_byte = _mm_set1_epi32(0xFF);
  const std::uint8_t* src = init_patch.data;
  const std::ptrdiff_t stride = init_patch.stride;
  const auto pair = [](const std::uint8_t* p) {  // p[0] | p[1] << 8, without reading past p[1]
    return static_cast<int>(p[0]) | static_cast<int>(p[1]) << 8;
  };
  // Lane coordinates of the group (exact small integers as doubles): (0..3, 0) wrapped at the row's end.
  __m256d vi = _mm256_set_pd(3.0, 2.0, 1.0, 0.0), vj = zero;
  for (int wrap = 0; wrap < 4; ++wrap) {
    const __m256d past = _mm256_cmp_pd(vi, width, _CMP_GE_OQ);
    vi = _mm256_sub_pd(vi, _mm256_and_pd(past, width));
    vj = _mm256_add_pd(vj, _mm256_and_pd(past, one));
  }
  int ci = 0, cj = 0;  // the group's first pixel
  const auto step = [w](int& x, int& y) {
    if (++x == w) {
      x = 0;
      ++y;
    }
  };
  int k = 0;
  for (; k + 4 <= total; k += 4) {
    const __m256d xh = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(g00, vi), _mm256_mul_pd(g01, vj)), g02);
    const __m256d yh = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(g10, vi), _mm256_mul_pd(g11, vj)), g12);
    const __m256d zh = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(g20, vi), _mm256_mul_pd(g21, vj)), g22);
    if (_mm256_movemask_pd(_mm256_cmp_pd(zh, zero, _CMP_GT_OQ)) != 0xF) {
      _mm256_zeroupper();
      return false;
    }
    const __m256d x0 = _mm256_div_pd(xh, zh), y0 = _mm256_div_pd(yh, zh);
    const __m256d pu = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(a00, x0), _mm256_mul_pd(a01, y0)), off_u);
    const __m256d pv = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(a10, x0), _mm256_mul_pd(a11, y0)), off_v);
    const __m256d inside =
        _mm256_and_pd(_mm256_and_pd(_mm256_cmp_pd(pu, zero, _CMP_GE_OQ), _mm256_cmp_pd(pu, max_u, _CMP_LT_OQ)),
                      _mm256_and_pd(_mm256_cmp_pd(pv, zero, _CMP_GE_OQ), _mm256_cmp_pd(pv, max_v, _CMP_LT_OQ)));
    int x = ci, y = cj;
    if (_mm256_movemask_pd(inside) != 0xF) {
      for (int l = 0; l < 4; ++l, step(x, y)) warp_pixel(m, init_patch, x, y, out.row(y)[x], n_outside);
    } else {
      const __m128i iu = _mm256_cvttpd_epi32(pu), iv = _mm256_cvttpd_epi32(pv);
      const __m256d fu = _mm256_sub_pd(pu, _mm256_cvtepi32_pd(iu));
      const __m256d fv = _mm256_sub_pd(pv, _mm256_cvtepi32_pd(iv));
      const __m128i offset = _mm_add_epi32(_mm_mullo_epi32(iv, _mm_set1_epi32(static_cast<int>(stride))), iu);
      const std::uint8_t* p0 = src + _mm_cvtsi128_si32(offset);
      const std::uint8_t* p1 = src + _mm_extract_epi32(offset, 1);
      const std::uint8_t* p2 = src + _mm_extract_epi32(offset, 2);
      const std::uint8_t* p3 = src + _mm_extract_epi32(offset, 3);
      const __m128i r0 = _mm_setr_epi32(pair(p0), pair(p1), pair(p2), pair(p3));
      const __m128i r1 = _mm_setr_epi32(pair(p0 + stride), pair(p1 + stride), pair(p2 + stride), pair(p3 + stride));
      const __m128i v00 = _mm_and_si128(r0, low_byte), v01 = _mm_srli_epi32(r0, 8);
      const __m128i v10 = _mm_and_si128(r1, low_byte), v11 = _mm_srli_epi32(r1, 8);
      const __m256d top =
          _mm256_add_pd(_mm256_cvtepi32_pd(v00), _mm256_mul_pd(fu, _mm256_cvtepi32_pd(_mm_sub_epi32(v01, v00))));
      const __m256d bottom =
          _mm256_add_pd(_mm256_cvtepi32_pd(v10), _mm256_mul_pd(fu, _mm256_cvtepi32_pd(_mm_sub_epi32(v11, v10))));
      const __m256d v = _mm256_add_pd(_mm256_add_pd(top, _mm256_mul_pd(fv, _mm256_sub_pd(bottom, top))), half);
      const __m128i bytes32 = _mm256_cvttpd_epi32(v);  // 0..255 each
      auto packed = static_cast<std::uint32_t>(
          _mm_cvtsi128_si32(_mm_packus_epi16(_mm_packus_epi32(bytes32, bytes32), _mm_setzero_si128())));
      for (int l = 0; l < 4; ++l, step(x, y), packed >>= 8) out.row(y)[x] = static_cast<std::uint8_t>(packed);
    }
    ci = x;
    cj = y;
    vi = _mm256_add_pd(vi, four);
    for (int wrap = 0; wrap < 4; ++wrap) {  // once when the patch is at least 4 wide
      const __m256d past = _mm256_cmp_pd(vi, width, _CMP_GE_OQ);
      if (_mm256_movemask_pd(past) == 0) break;
      vi = _mm256_sub_pd(vi, _mm256_and_pd(past, width));
      vj = _mm256_add_pd(vj, _mm256_and_pd(past, one));
    }
  }
  _mm256_zeroupper();  // before plain SSE code (see simd.hpp)
  for (; k < total; ++k, step(ci, cj)) {
    if (!warp_pixel(m, init_patch, ci, cj, out.row(cj)[ci], n_outside)) return false;
  }
  return true;
}
#endif

}  // namespace

WarpResult predict_appearance(ImageView init_patch, const Eigen::Vector2d& init_centre_px,
                              const PinholeIntrinsics& K, const RigidPose& T_WC0, const RigidPose& T_WC,
                              const Eigen::Vector3d& p_W, MutableImageView out, const LocalDistortion* distortion) {
  WarpResult res;
  Eigen::Matrix3d H;
  if (init_patch.empty() || out.width <= 0 || out.height <= 0 || !plane_homography(K, T_WC0, T_WC, p_W, &H)) {
    return res;
  }
  const double det = H.determinant();
  if (!(std::abs(det) > 1e-300) || !std::isfinite(det)) return res;
  const Eigen::Matrix3d H_inv = H.inverse();
  const Eigen::Vector3d p_C0 = T_WC0.R.transpose() * (p_W - T_WC0.t);
  const Eigen::Vector3d p_C1 = T_WC.R.transpose() * (p_W - T_WC.t);
  const Eigen::Vector2d c0 = project(K, p_C0);
  const Eigen::Vector2d c1 = project(K, p_C1);
  res.centre_px = c1;

  // Output pixel (i, j) -> distorted offset δd = (i - ho, j - ho) -> undistorted current pixel
  // q = c1 + A1⁻¹ δd -> x0 ~ H⁻¹ q -> patch coordinates (hi, hi) + x0d - init_centre, x0d = c0d + A0 (x0 - c0).
  Eigen::Matrix2d A1_inv = Eigen::Matrix2d::Identity();
  Eigen::Matrix2d A0 = Eigen::Matrix2d::Identity();
  Eigen::Vector2d c0d = c0;
  if (distortion != nullptr) {
    A1_inv = distortion->J_dist_undist.inverse();
    A0 = distortion->J_dist_undist_0;
    c0d = distortion->centre0_dist_px;
  }
  const double ho_u = 0.5 * (out.width - 1), ho_v = 0.5 * (out.height - 1);
  Eigen::Matrix3d Q = Eigen::Matrix3d::Identity();  // (i, j, 1) -> homogeneous q
  Q.topLeftCorner<2, 2>() = A1_inv;
  Q.topRightCorner<2, 1>() = c1 - A1_inv * Eigen::Vector2d(ho_u, ho_v);
  const Eigen::Matrix3d G = H_inv * Q;  // (i, j, 1) -> homogeneous x0
  const double hi_u = 0.5 * (init_patch.width - 1), hi_v = 0.5 * (init_patch.height - 1);
  const Eigen::Vector2d off = Eigen::Vector2d(hi_u, hi_v) - init_centre_px + c0d - A0 * c0;

  PixelMap map;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) map.G[r][c] = G(r, c);
  map.A0[0][0] = A0(0, 0);
  map.A0[0][1] = A0(0, 1);
  map.A0[1][0] = A0(1, 0);
  map.A0[1][1] = A0(1, 1);
  map.off_u = off.x();
  map.off_v = off.y();
  map.max_u = init_patch.width - 1;
  map.max_v = init_patch.height - 1;
#if defined(__x86_64__)
  const bool ok = simd_level() == SimdLevel::avx2 ? warp_avx2(map, init_patch, out, res.n_outside)
                                                  : warp_scalar(map, init_patch, out, res.n_outside);
#else
  const bool ok = warp_scalar(map, init_patch, out, res.n_outside);
#endif
  if (!ok) return WarpResult{};  // a pixel's ray misses the plane in front of C0
  res.ok = true;
  return res;
}

}  // namespace rtslam::vision
