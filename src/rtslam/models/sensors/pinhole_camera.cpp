#include "rtslam/models/sensors/pinhole_camera.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <fmt/format.h>
#include <Eigen/Dense>

#include "rtslam/core/error.hpp"

namespace rtslam::models {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kMaxRtslamPolyCoeffs = 8;
constexpr int kMaxCorrectionCoeffs = 8;

/// Evaluates 1 + c0 s + c1 s² + ... and its derivative with respect to s (Horner).
std::pair<double, double> radial_poly(const std::vector<double>& c, std::size_t n, double s) {
  double val = 0.0;
  double der = 0.0;
  for (std::size_t i = n; i-- > 0;) {
    der = der * s + val;
    val = val * s + c[i];
  }
  // val = c0 + c1 s + ...; the polynomial is 1 + s·val, its derivative val + s·der.
  return {1.0 + s * val, val + s * der};
}

/// Smallest t in (0, t_end) where g(t) <= 0 (g(0) > 0), found by a geometric scan and bisection; t_end if none.
template <class G>
double first_non_positive(const G& g, double t_end) {
  double prev = 0.0;
  for (double t = 1e-4; t < t_end; t *= 1.002) {
    if (g(t) <= 0.0) {
      double lo = prev;
      double hi = t;
      for (int i = 0; i < 200 && hi - lo > 1e-15 * hi; ++i) {
        const double mid = 0.5 * (lo + hi);
        (g(mid) <= 0.0 ? hi : lo) = mid;
      }
      return lo;
    }
    prev = t;
  }
  return t_end;
}

}  // namespace

std::string to_string(DistortionModel model) {
  switch (model) {
    case DistortionModel::None:
      return "none";
    case DistortionModel::RadTan:
      return "radial-tangential";
    case DistortionModel::Equidistant:
      return "equidistant";
    case DistortionModel::MonoSlam:
      return "monoslam";
    case DistortionModel::RtslamPoly:
      return "rtslam-poly";
  }
  return "unknown";
}

DistortionModel distortion_model_from_string(const std::string& name) {
  if (name == "none") return DistortionModel::None;
  if (name == "radial-tangential" || name == "radtan" || name == "pinhole-radtan") return DistortionModel::RadTan;
  if (name == "equidistant" || name == "fisheye" || name == "pinhole-equi") return DistortionModel::Equidistant;
  if (name == "monoslam") return DistortionModel::MonoSlam;
  if (name == "rtslam-poly" || name == "poly") return DistortionModel::RtslamPoly;
  throw ConfigError(fmt::format(
      "distortion model '{}' is unknown (expected none, radial-tangential, equidistant, monoslam, rtslam-poly)", name));
}

void CameraIntrinsics::validate() const {
  if (width <= 0 || height <= 0) {
    throw ConfigError(fmt::format("camera intrinsics: image size {}x{} must be positive", width, height));
  }
  if (!(std::isfinite(fx) && fx > 0.0)) throw ConfigError(fmt::format("camera intrinsics: fx = {} must be > 0", fx));
  if (!(std::isfinite(fy) && fy > 0.0)) throw ConfigError(fmt::format("camera intrinsics: fy = {} must be > 0", fy));
  if (!std::isfinite(cx)) throw ConfigError(fmt::format("camera intrinsics: cx = {} must be finite", cx));
  if (!std::isfinite(cy)) throw ConfigError(fmt::format("camera intrinsics: cy = {} must be finite", cy));
  const std::size_t n = coeffs.size();
  bool count_ok = true;
  const char* expected = "";
  switch (model) {
    case DistortionModel::None:
      count_ok = n == 0;
      expected = "0";
      break;
    case DistortionModel::RadTan:
      count_ok = n == 4 || n == 5;
      expected = "4 or 5 (k1 k2 p1 p2 [k3])";
      break;
    case DistortionModel::Equidistant:
      count_ok = n == 4;
      expected = "4 (k1 k2 k3 k4)";
      break;
    case DistortionModel::MonoSlam:
      count_ok = n == 1;
      expected = "1 (kappa)";
      break;
    case DistortionModel::RtslamPoly:
      count_ok = n <= static_cast<std::size_t>(kMaxRtslamPolyCoeffs);
      expected = "0 to 8 (d0 d1 ...)";
      break;
  }
  if (!count_ok) {
    throw ConfigError(fmt::format("camera intrinsics: distortion '{}' has {} coefficients, expected {}",
                                  to_string(model), n, expected));
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(coeffs[i])) {
      throw ConfigError(fmt::format("camera intrinsics: distortion coefficient {} = {} must be finite", i, coeffs[i]));
    }
  }
}

PinholeCamera::PinholeCamera(CameraIntrinsics intr) : intr_(std::move(intr)) {
  intr_.validate();
  if (intr_.model == DistortionModel::RadTan && intr_.coeffs.size() == 4) intr_.coeffs.push_back(0.0);
  compute_domain();
  if (intr_.model == DistortionModel::RtslamPoly) fit_correction();
}

void PinholeCamera::compute_domain() {
  const auto& c = intr_.coeffs;
  switch (intr_.model) {
    case DistortionModel::None:
    case DistortionModel::MonoSlam:  // its domain is checked on pixel radii in distort()
      r_max_ = kInf;
      rd_max_ = kInf;
      break;
    case DistortionModel::RadTan:
    case DistortionModel::RtslamPoly: {
      // Radial map r -> r k(r²) must increase: k(r²) + 2 r² k'(r²) > 0. Scan up to r = 1e3 (89.94°).
      const std::size_t n = intr_.model == DistortionModel::RadTan ? 3 : c.size();
      std::vector<double> radial(c.begin(), c.end());
      if (intr_.model == DistortionModel::RadTan) radial = {c[0], c[1], c[4]};
      const auto g = [&](double r) {
        const double s = r * r;
        const auto [k, dk] = radial_poly(radial, n, s);
        return k + 2.0 * s * dk;
      };
      const double r = first_non_positive(g, 1e3);
      r_max_ = r >= 1e3 ? kInf : r;
      rd_max_ = std::isfinite(r_max_) ? r_max_ * radial_poly(radial, n, r_max_ * r_max_).first : kInf;
      break;
    }
    case DistortionModel::Equidistant: {
      // θ -> θ_d must increase on [0, π/2): 1 + 3k1θ² + 5k2θ⁴ + 7k3θ⁶ + 9k4θ⁸ > 0.
      const auto g = [&](double th) {
        const double t2 = th * th;
        return 1.0 + t2 * (3.0 * c[0] + t2 * (5.0 * c[1] + t2 * (7.0 * c[2] + t2 * 9.0 * c[3])));
      };
      const double th = first_non_positive(g, 0.5 * M_PI);
      r_max_ = th >= 0.5 * M_PI ? kInf : std::tan(th);
      const double t2 = th * th;
      rd_max_ = th * (1.0 + t2 * (c[0] + t2 * (c[1] + t2 * (c[2] + t2 * c[3]))));
      break;
    }
  }
}

void PinholeCamera::fit_correction() {
  // Fit c(r_d²) = r_u / r_d = 1 + c0 r_d² + c1 r_d⁴ + ... over the distorted radii the image can show.
  const std::vector<double>& d = intr_.coeffs;
  if (d.empty()) return;
  const auto radial = [&](double r) { return r * radial_poly(d, d.size(), r * r).first; };
  double rd_max = 0.0;
  for (double u : {0.0, intr_.width - 1.0}) {
    for (double v : {0.0, intr_.height - 1.0}) {
      rd_max = std::max(rd_max, std::hypot((u - intr_.cx) / intr_.fx, (v - intr_.cy) / intr_.fy));
    }
  }
  if (std::isfinite(r_max_)) rd_max = std::min(rd_max, 0.999 * radial(r_max_));
  if (!(rd_max > 0.0)) return;
  const int n_c = std::min(kMaxCorrectionCoeffs, 2 * static_cast<int>(d.size()) + 1);
  const int n_samples = 200;
  Eigen::MatrixXd A(n_samples, n_c);
  Eigen::VectorXd b(n_samples);
  for (int i = 0; i < n_samples; ++i) {
    const double rd = rd_max * (i + 1) / n_samples;
    // Exact inverse of the monotonic radial map by bisection.
    double lo = 0.0;
    double hi = std::isfinite(r_max_) ? r_max_ : 2.0 * rd;
    while (!std::isfinite(r_max_) && radial(hi) < rd) hi *= 2.0;
    for (int it = 0; it < 200 && hi - lo > 1e-16 * hi; ++it) {
      const double mid = 0.5 * (lo + hi);
      (radial(mid) < rd ? lo : hi) = mid;
    }
    const double ru = 0.5 * (lo + hi);
    // Columns in the scaled variable s = (r_d / rd_max)² for conditioning.
    const double s = (rd / rd_max) * (rd / rd_max);
    double sp = 1.0;
    for (int j = 0; j < n_c; ++j) {
      sp *= s;
      A(i, j) = sp;
    }
    b[i] = ru / rd - 1.0;
  }
  const Eigen::VectorXd c = A.colPivHouseholderQr().solve(b);
  correction_.resize(n_c);
  const double rd2 = rd_max * rd_max;
  double scale = 1.0;
  for (int j = 0; j < n_c; ++j) {
    scale *= rd2;
    correction_[j] = c[j] / scale;
  }
}

Eigen::Vector2d PinholeCamera::undistort_by_correction(const Eigen::Vector2d& xy_d) const {
  if (intr_.model != DistortionModel::RtslamPoly || correction_.empty()) return xy_d;
  return radial_poly(correction_, correction_.size(), xy_d.squaredNorm()).first * xy_d;
}

bool PinholeCamera::distort(const Eigen::Vector2d& xy, Eigen::Vector2d& xy_d, Eigen::Matrix2d* J) const {
  const auto& c = intr_.coeffs;
  const double x = xy.x();
  const double y = xy.y();
  const double r2 = x * x + y * y;
  switch (intr_.model) {
    case DistortionModel::None:
      xy_d = xy;
      if (J) J->setIdentity();
      return true;
    case DistortionModel::RadTan: {
      if (!(r2 < r_max_ * r_max_)) return false;
      const double k1 = c[0], k2 = c[1], p1 = c[2], p2 = c[3], k3 = c[4];
      const double k = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
      xy_d.x() = k * x + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
      xy_d.y() = k * y + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
      if (J) {
        const double kp = k1 + r2 * (2.0 * k2 + r2 * 3.0 * k3);  // dk/d(r²)
        (*J)(0, 0) = k + 2.0 * x * x * kp + 2.0 * p1 * y + 6.0 * p2 * x;
        (*J)(0, 1) = 2.0 * x * y * kp + 2.0 * p1 * x + 2.0 * p2 * y;
        (*J)(1, 0) = (*J)(0, 1);
        (*J)(1, 1) = k + 2.0 * y * y * kp + 6.0 * p1 * y + 2.0 * p2 * x;
      }
      return true;
    }
    case DistortionModel::RtslamPoly: {
      if (!(r2 < r_max_ * r_max_)) return false;
      const auto [k, kp] = radial_poly(c, c.size(), r2);
      xy_d = k * xy;
      if (J) *J = k * Eigen::Matrix2d::Identity() + 2.0 * kp * xy * xy.transpose();
      return true;
    }
    case DistortionModel::Equidistant: {
      const double r = std::sqrt(r2);
      if (!(r < r_max_)) return false;
      const double k1 = c[0], k2 = c[1], k3 = c[2], k4 = c[3];
      double s;   // θ_d / r
      double gs;  // (ds/dr) / r
      if (r < 1e-5) {
        // θ_d / r = 1 + (k1 − 1/3) r² + O(r⁴).
        s = 1.0 + (k1 - 1.0 / 3.0) * r2;
        gs = 2.0 * (k1 - 1.0 / 3.0);
      } else {
        const double th = std::atan(r);
        const double t2 = th * th;
        const double th_d = th * (1.0 + t2 * (k1 + t2 * (k2 + t2 * (k3 + t2 * k4))));
        const double dthd_dth = 1.0 + t2 * (3.0 * k1 + t2 * (5.0 * k2 + t2 * (7.0 * k3 + t2 * 9.0 * k4)));
        const double dth_dr = 1.0 / (1.0 + r2);
        s = th_d / r;
        gs = (dthd_dth * dth_dr * r - th_d) / (r2 * r);
      }
      xy_d = s * xy;
      if (J) *J = s * Eigen::Matrix2d::Identity() + gs * xy * xy.transpose();
      return true;
    }
    case DistortionModel::MonoSlam: {
      // On pixel offsets du = D xy, D = diag(fx, fy): dd = du / sqrt(1 + 2κ|du|²).
      const double kappa = c[0];
      const Eigen::Vector2d du(intr_.fx * x, intr_.fy * y);
      const double a = 1.0 + 2.0 * kappa * du.squaredNorm();
      if (!(a > 0.0)) return false;
      const double s = 1.0 / std::sqrt(a);
      const Eigen::Vector2d dd = s * du;
      xy_d = Eigen::Vector2d(dd.x() / intr_.fx, dd.y() / intr_.fy);
      if (J) {
        const Eigen::Matrix2d J_dd_du = s * Eigen::Matrix2d::Identity() - 2.0 * kappa * s * s * s * du * du.transpose();
        // J = D⁻¹ J_dd_du D.
        (*J)(0, 0) = J_dd_du(0, 0);
        (*J)(0, 1) = J_dd_du(0, 1) * intr_.fy / intr_.fx;
        (*J)(1, 0) = J_dd_du(1, 0) * intr_.fx / intr_.fy;
        (*J)(1, 1) = J_dd_du(1, 1);
      }
      return true;
    }
  }
  return false;
}

bool PinholeCamera::undistort(const Eigen::Vector2d& xy_d, Eigen::Vector2d& xy, Eigen::Matrix2d* J) const {
  switch (intr_.model) {
    case DistortionModel::None:
      xy = xy_d;
      if (J) J->setIdentity();
      return true;
    case DistortionModel::MonoSlam: {
      // du = dd / sqrt(1 − 2κ|dd|²) on pixel offsets dd = D xy_d.
      const double kappa = intr_.coeffs[0];
      const Eigen::Vector2d dd(intr_.fx * xy_d.x(), intr_.fy * xy_d.y());
      const double a = 1.0 - 2.0 * kappa * dd.squaredNorm();
      if (!(a > 0.0)) return false;
      const double s = 1.0 / std::sqrt(a);
      xy = Eigen::Vector2d(s * xy_d.x(), s * xy_d.y());
      if (J) {
        const Eigen::Matrix2d J_du_dd = s * Eigen::Matrix2d::Identity() + 2.0 * kappa * s * s * s * dd * dd.transpose();
        (*J)(0, 0) = J_du_dd(0, 0);
        (*J)(0, 1) = J_du_dd(0, 1) * intr_.fy / intr_.fx;
        (*J)(1, 0) = J_du_dd(1, 0) * intr_.fx / intr_.fy;
        (*J)(1, 1) = J_du_dd(1, 1);
      }
      return true;
    }
    case DistortionModel::RadTan:
    case DistortionModel::Equidistant:
    case DistortionModel::RtslamPoly:
      break;
  }
  if (!xy_d.allFinite()) return false;
  // Radial models: a distorted radius at or beyond the fold (or 90° for the fisheye) has no valid preimage.
  // (RadTan's tangential terms make this bound approximate there, so it relies on Newton alone.)
  if (intr_.model != DistortionModel::RadTan && !(xy_d.norm() < rd_max_)) return false;
  // Newton on distort(xy) = xy_d with backtracking; the residual is measured in pixels, compared squared (the
  // renderer's ray table unprojects ~1.4 million sub-pixels, and std::hypot took ~45 % of that). A square overflows
  // only for residuals beyond ~1e154 px: it is then infinite (or NaN), and only a step to a finite one is accepted.
  const auto squared_residual_px = [&](const Eigen::Vector2d& d) {
    const double ex = intr_.fx * (d.x() - xy_d.x()), ey = intr_.fy * (d.y() - xy_d.y());
    return ex * ex + ey * ey;
  };
  Eigen::Vector2d cur = undistort_by_correction(xy_d);
  Eigen::Vector2d d;
  Eigen::Matrix2d Jd;
  if (!distort(cur, d, &Jd)) {
    cur = xy_d;
    if (!distort(cur, d, &Jd)) return false;
  }
  double res = squared_residual_px(d);
  constexpr double kTolerance2 = kUnprojectTolerancePx * kUnprojectTolerancePx;
  bool converged = res <= kTolerance2;
  for (int it = 0; it < 50 && !converged; ++it) {
    const double det = Jd.determinant();
    if (!(std::abs(det) > 1e-300)) return false;
    const Eigen::Vector2d step = Jd.inverse() * (d - xy_d);
    bool accepted = false;
    double t = 1.0;
    for (int k = 0; k < 60; ++k, t *= 0.5) {
      const Eigen::Vector2d cand = cur - t * step;
      Eigen::Vector2d dc;
      if (!distort(cand, dc)) continue;
      const double rc = squared_residual_px(dc);
      if (rc < res) {
        cur = cand;
        res = rc;
        accepted = true;
        break;
      }
    }
    if (!accepted) return false;
    distort(cur, d, &Jd);
    converged = res <= kTolerance2;
  }
  if (!converged) return false;
  xy = cur;
  if (J) *J = Jd.inverse();
  return true;
}

bool PinholeCamera::project(const Eigen::Vector3d& p_C, Eigen::Vector2d& px,
                            Eigen::Matrix<double, 2, 3>* J_px_pC) const {
  const double z = p_C.z();
  if (!(z > kMinDepth * p_C.norm())) return false;
  const double iz = 1.0 / z;
  const Eigen::Vector2d xy(p_C.x() * iz, p_C.y() * iz);
  Eigen::Vector2d xy_d;
  Eigen::Matrix2d J_d;
  if (!distort(xy, xy_d, J_px_pC ? &J_d : nullptr)) return false;
  px = Eigen::Vector2d(intr_.fx * xy_d.x() + intr_.cx, intr_.fy * xy_d.y() + intr_.cy);
  if (J_px_pC) {
    Eigen::Matrix<double, 2, 3> J_xy_p;
    J_xy_p << iz, 0.0, -xy.x() * iz, 0.0, iz, -xy.y() * iz;
    const Eigen::Matrix<double, 2, 3> J_xyd_p = J_d * J_xy_p;
    J_px_pC->row(0) = intr_.fx * J_xyd_p.row(0);
    J_px_pC->row(1) = intr_.fy * J_xyd_p.row(1);
  }
  return true;
}

bool PinholeCamera::in_image(const Eigen::Vector2d& px, double margin) const {
  return px.x() >= margin && px.x() <= intr_.width - 1 - margin && px.y() >= margin &&
         px.y() <= intr_.height - 1 - margin;
}

bool PinholeCamera::unproject(const Eigen::Vector2d& px, Eigen::Vector3d& ray_C,
                              Eigen::Matrix<double, 3, 2>* J_ray_px) const {
  const Eigen::Vector2d xy_d((px.x() - intr_.cx) / intr_.fx, (px.y() - intr_.cy) / intr_.fy);
  Eigen::Vector2d xy;
  Eigen::Matrix2d J_u;
  if (!undistort(xy_d, xy, J_ray_px ? &J_u : nullptr)) return false;
  ray_C = Eigen::Vector3d(xy.x(), xy.y(), 1.0);
  if (J_ray_px) {
    J_ray_px->setZero();
    J_ray_px->col(0).head<2>() = J_u.col(0) / intr_.fx;
    J_ray_px->col(1).head<2>() = J_u.col(1) / intr_.fy;
  }
  return true;
}

}  // namespace rtslam::models
