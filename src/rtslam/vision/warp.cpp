#include "rtslam/vision/warp.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/LU>

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

  const double max_u = init_patch.width - 1, max_v = init_patch.height - 1;
  for (int j = 0; j < out.height; ++j) {
    std::uint8_t* dst = out.row(j);
    for (int i = 0; i < out.width; ++i) {
      const double xh = G(0, 0) * i + G(0, 1) * j + G(0, 2);
      const double yh = G(1, 0) * i + G(1, 1) * j + G(1, 2);
      const double zh = G(2, 0) * i + G(2, 1) * j + G(2, 2);
      if (!(zh > 0.0)) return WarpResult{};  // the pixel's ray misses the plane in front of C0
      const double x0 = xh / zh, y0 = yh / zh;
      double pu = A0(0, 0) * x0 + A0(0, 1) * y0 + off.x();
      double pv = A0(1, 0) * x0 + A0(1, 1) * y0 + off.y();
      if (pu >= 0.0 && pu < max_u && pv >= 0.0 && pv < max_v) {  // inside: plain bilinear, no clamping
        const int iu = static_cast<int>(pu), iv = static_cast<int>(pv);
        const double fu = pu - iu, fv = pv - iv;
        const std::uint8_t* p0 = init_patch.row(iv) + iu;
        const std::uint8_t* p1 = p0 + init_patch.stride;
        const double top = p0[0] + fu * (p0[1] - p0[0]);
        const double bottom = p1[0] + fu * (p1[1] - p1[0]);
        dst[i] = static_cast<std::uint8_t>(top + fv * (bottom - top) + 0.5);
        continue;
      }
      if (!(pu >= 0.0 && pu <= max_u && pv >= 0.0 && pv <= max_v)) ++res.n_outside;
      pu = std::clamp(pu, 0.0, max_u);
      pv = std::clamp(pv, 0.0, max_v);
      dst[i] = static_cast<std::uint8_t>(sample_bilinear(init_patch, pu, pv) + 0.5);
    }
  }
  res.ok = true;
  return res;
}

}  // namespace rtslam::vision
