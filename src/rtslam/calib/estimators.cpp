#include "rtslam/calib/estimators.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include "rtslam/math/rotation.hpp"

namespace rtslam::calib {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

namespace {

Matrix3d exp_mat(const Vector3d& theta) { return math::exp_so3(theta).toRotationMatrix(); }

// Sampson error of x0ᵀ E x1 = 0 (x on the z = 1 plane), E = [t]× R.
double sampson(const Matrix3d& E, const Vector3d& x0, const Vector3d& x1) {
  const Vector3d Ex1 = E * x1;
  const Vector3d Etx0 = E.transpose() * x0;
  const double den = Ex1.head<2>().squaredNorm() + Etx0.head<2>().squaredNorm();
  return den > 1e-30 ? x0.dot(Ex1) / std::sqrt(den) : 0.0;
}

// Two unit vectors orthogonal to t (a basis of its tangent plane).
Eigen::Matrix<double, 3, 2> tangent_basis(const Vector3d& t) {
  const Vector3d a = std::abs(t.x()) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY();
  const Vector3d u = t.cross(a).normalized();
  Eigen::Matrix<double, 3, 2> B;
  B.col(0) = u;
  B.col(1) = t.cross(u);
  return B;
}

}  // namespace

Matrix3d kabsch(const std::vector<Vector3d>& a, const std::vector<Vector3d>& b, const std::vector<double>& w) {
  Matrix3d M = Matrix3d::Zero();
  for (std::size_t i = 0; i < a.size() && i < b.size(); ++i) {
    M += (w.empty() ? 1.0 : w[i]) * a[i] * b[i].transpose();
  }
  Eigen::JacobiSVD<Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  if (svd.singularValues()(1) <= 1e-12 * std::max(1.0, svd.singularValues()(0))) return Matrix3d::Identity();
  Matrix3d D = Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixU() * D * svd.matrixV().transpose();
}

RelativeRotation estimate_relative_rotation(const std::vector<Vector3d>& b0_in, const std::vector<Vector3d>& b1_in,
                                            const RelativeRotationOptions& o, Rng& rng) {
  RelativeRotation res;
  const std::size_t n = std::min(b0_in.size(), b1_in.size());
  if (static_cast<int>(n) < std::max(o.min_inliers, 2)) return res;
  std::vector<Vector3d> b0(n), b1(n);
  for (std::size_t k = 0; k < n; ++k) {
    b0[k] = b0_in[k].normalized();
    b1[k] = b1_in[k].normalized();
  }
  // 1. RANSAC over the pure rotation (2 bearings fix it); the threshold leaves room for the parallax of translation.
  const double cos_th = std::cos(o.ransac_threshold);
  std::vector<char> best_in(n, 0), in(n, 0);
  int best_count = 0;
  std::uniform_int_distribution<std::size_t> pick(0, n - 1);
  std::vector<Vector3d> sa(2), sb(2);
  for (int it = 0; it < o.ransac_iterations; ++it) {
    const std::size_t i = pick(rng);
    std::size_t j = pick(rng);
    if (j == i) j = (i + 1) % n;
    if (b0[i].cross(b0[j]).norm() < 0.02) continue;  // nearly parallel: the rotation about them is free
    sa = {b0[i], b0[j]};
    sb = {b1[i], b1[j]};
    const Matrix3d R = kabsch(sa, sb);
    int count = 0;
    for (std::size_t k = 0; k < n; ++k) {
      in[k] = b0[k].dot(R * b1[k]) >= cos_th ? 1 : 0;
      count += in[k];
    }
    if (count > best_count) {
      best_count = count;
      best_in = in;
    }
  }
  if (best_count < o.min_inliers) return res;
  std::vector<Vector3d> ia, ib;
  for (std::size_t k = 0; k < n; ++k) {
    if (best_in[k]) {
      ia.push_back(b0[k]);
      ib.push_back(b1[k]);
    }
  }
  Matrix3d R = kabsch(ia, ib);
  // Inliers of the refined rotation.
  ia.clear();
  ib.clear();
  for (std::size_t k = 0; k < n; ++k) {
    if (b0[k].dot(R * b1[k]) >= cos_th) {
      ia.push_back(b0[k]);
      ib.push_back(b1[k]);
    }
  }
  if (static_cast<int>(ia.size()) < o.min_inliers) return res;
  R = kabsch(ia, ib);
  res.R_01 = R;
  res.inliers = static_cast<int>(ia.size());
  if (!o.epipolar) {
    double s = 0.0;
    for (std::size_t k = 0; k < ia.size(); ++k) s += (ia[k] - R * ib[k]).squaredNorm();
    res.rms = std::sqrt(s / static_cast<double>(ia.size()));
    res.ok = true;
    return res;
  }

  // 2. The epipolar model x0ᵀ [t]× R x1 = 0 over every pair with z > 0, robust Levenberg-Marquardt on the Sampson
  // error (numeric Jacobians: 5 parameters), the translation direction started at the least-squares null vector.
  // Active set: the rotation model's (loose) inliers first, then the epipolar model's own.
  std::vector<Vector3d> all0, all1, x0, x1;
  for (std::size_t k = 0; k < n; ++k) {
    if (b0[k].z() > 0.05 && b1[k].z() > 0.05) {
      all0.push_back(b0[k] / b0[k].z());
      all1.push_back(b1[k] / b1[k].z());
      if (b0[k].dot(R * b1[k]) >= cos_th) {
        x0.push_back(all0.back());
        x1.push_back(all1.back());
      }
    }
  }
  if (static_cast<int>(x0.size()) < o.min_inliers) return res;
  Vector3d t;
  {
    Matrix3d A = Matrix3d::Zero();
    for (std::size_t k = 0; k < x0.size(); ++k) {
      const Vector3d a = (R * x1[k]).cross(x0[k]);
      A += a * a.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Matrix3d> es(A);
    t = es.eigenvectors().col(0);
  }
  const auto residuals = [&](const Matrix3d& Rx, const Vector3d& tx, Eigen::VectorXd& r) {
    const Matrix3d E = math::skew(tx) * Rx;
    r.resize(static_cast<Eigen::Index>(x0.size()));
    for (std::size_t k = 0; k < x0.size(); ++k) r[static_cast<Eigen::Index>(k)] = sampson(E, x0[k], x1[k]);
  };
  const double huber = o.sampson_threshold;
  const auto robust_cost = [&](const Eigen::VectorXd& r, Eigen::VectorXd* w) {
    double c = 0.0;
    if (w) w->resize(r.size());
    for (Eigen::Index k = 0; k < r.size(); ++k) {
      const double a = std::abs(r[k]);
      // Cauchy-like: far outliers have almost no influence.
      const double s = a / (3.0 * huber);
      c += std::log1p(s * s);
      if (w) (*w)[k] = 1.0 / (1.0 + s * s);
    }
    return c;
  };
  struct Fit {
    Matrix3d R;
    Vector3d t;
    Eigen::VectorXd r;
    double cost;
  };
  const auto refine = [&](Matrix3d Rf, Vector3d tf) {
    Eigen::VectorXd r, w, r_try, w_try, rp;
    residuals(Rf, tf, r);
    double cost = robust_cost(r, &w);
    double lambda = 1e-3;
    Eigen::MatrixXd J(static_cast<Eigen::Index>(x0.size()), 5);
    for (int it = 0; it < 30; ++it) {
      const Eigen::Matrix<double, 3, 2> B = tangent_basis(tf);
      const double h = 1e-7;
      for (int p = 0; p < 5; ++p) {
        Eigen::Matrix<double, 5, 1> d = Eigen::Matrix<double, 5, 1>::Zero();
        d[p] = h;
        residuals(Rf * exp_mat(d.head<3>()), (tf + B * d.tail<2>()).normalized(), rp);
        J.col(p) = (rp - r) / h;
      }
      const Eigen::MatrixXd Jw = w.asDiagonal() * J;
      const Eigen::Matrix<double, 5, 5> H = J.transpose() * Jw;
      const Eigen::Matrix<double, 5, 1> g = Jw.transpose() * r;
      bool improved = false, converged = false;
      for (int tries = 0; tries < 8 && !improved; ++tries) {
        Eigen::Matrix<double, 5, 5> Hd = H;
        for (int p = 0; p < 5; ++p) Hd(p, p) += lambda * std::max(H(p, p), 1e-12);
        const Eigen::Matrix<double, 5, 1> d = -Hd.ldlt().solve(g);
        if (!d.allFinite()) break;
        const Matrix3d Rn = Rf * exp_mat(d.head<3>());
        const Vector3d tn = (tf + B * d.tail<2>()).normalized();
        residuals(Rn, tn, r_try);
        const double c = robust_cost(r_try, &w_try);
        if (c < cost) {
          converged = (cost - c) < 1e-10 * std::max(cost, 1e-30) || d.norm() < 1e-10;
          Rf = Rn;
          tf = tn;
          r.swap(r_try);
          w.swap(w_try);
          cost = c;
          lambda = std::max(lambda * 0.3, 1e-7);
          improved = true;
        } else {
          lambda *= 10.0;
        }
      }
      if (!improved || converged) break;
    }
    return Fit{Rf, tf, r, cost};
  };
  // Several starts of the translation direction: with small baselines the epipolar cost has local minima where
  // translation and rotation trade (the rotation-only start sits near one of them).
  Fit best = refine(R, t);
  for (const Vector3d& t0 : {Vector3d(1, 0, 0), Vector3d(0, 1, 0), Vector3d(0, 0, 1), Vector3d(1, 1, 1).normalized(),
                             Vector3d(1, -1, 1).normalized(), Vector3d(-1, 1, 1).normalized(),
                             Vector3d(1, 1, -1).normalized()}) {
    Fit f = refine(res.R_01, t0);
    if (f.cost < best.cost) best = std::move(f);
  }
  // The epipolar model's inliers among every pair (a rotation-model outlier may be a near point), refined once more.
  for (const double factor : {3.0, 2.0, 1.5}) {
    const Matrix3d E = math::skew(best.t) * best.R;
    x0.clear();
    x1.clear();
    for (std::size_t k = 0; k < all0.size(); ++k) {
      if (std::abs(sampson(E, all0[k], all1[k])) <= factor * o.sampson_threshold) {
        x0.push_back(all0[k]);
        x1.push_back(all1[k]);
      }
    }
    if (static_cast<int>(x0.size()) < o.min_inliers) return res;
    best = refine(best.R, best.t);
  }
  R = best.R;
  t = best.t;
  const Eigen::VectorXd& r = best.r;
  int inl = 0;
  double s = 0.0;
  for (Eigen::Index k = 0; k < r.size(); ++k) {
    if (std::abs(r[k]) <= o.sampson_threshold) {
      ++inl;
      s += r[k] * r[k];
    }
  }
  if (inl < o.min_inliers) return res;
  res.R_01 = R;
  res.t_01 = t;
  res.inliers = inl;
  res.rms = std::sqrt(s / inl);
  res.ok = true;
  return res;
}

std::optional<Vector3d> integrate_gyro(const std::vector<io::ImuSample>& imu, TimeNs a, TimeNs b, const Vector3d& bias,
                                       TimeNs max_gap) {
  if (imu.size() < 2 || b < a || imu.front().t > a || imu.back().t < b) return std::nullopt;
  // k: the last sample at or before a.
  auto it = std::upper_bound(imu.begin(), imu.end(), a, [](TimeNs t, const io::ImuSample& s) { return t < s.t; });
  std::size_t k = static_cast<std::size_t>(it - imu.begin()) - 1;
  const auto rate_at = [&](std::size_t i, TimeNs t) -> Vector3d {
    const io::ImuSample& s0 = imu[i];
    if (i + 1 >= imu.size() || imu[i + 1].t == s0.t) return s0.gyro;
    const io::ImuSample& s1 = imu[i + 1];
    const double f = static_cast<double>(t - s0.t) / static_cast<double>(s1.t - s0.t);
    return s0.gyro + f * (s1.gyro - s0.gyro);
  };
  Quaterniond q = Quaterniond::Identity();
  TimeNs t = a;
  Vector3d w_prev = rate_at(k, a);
  while (t < b) {
    if (k + 1 >= imu.size()) return std::nullopt;
    if (imu[k + 1].t - imu[k].t > max_gap) return std::nullopt;
    const TimeNs t_next = std::min(imu[k + 1].t, b);
    const Vector3d w_next = t_next == imu[k + 1].t ? imu[k + 1].gyro : rate_at(k, t_next);
    const double dt = to_seconds(t_next - t);
    if (dt > 0.0) q = q * math::exp_so3((0.5 * (w_prev + w_next) - bias) * dt);
    t = t_next;
    w_prev = w_next;
    if (t_next == imu[k + 1].t) ++k;
  }
  return math::log_so3(q.normalized());
}

namespace {

// Pearson correlation of two equally long series.
double pearson(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  if (x.size() < 3) return 0.0;
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / n;
  const double my = std::accumulate(y.begin(), y.end(), 0.0) / n;
  double sxy = 0.0, sxx = 0.0, syy = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
    syy += (y[i] - my) * (y[i] - my);
  }
  return sxx > 0.0 && syy > 0.0 ? sxy / std::sqrt(sxx * syy) : 0.0;
}

// Clips a series to its median ± 3 robust sigmas (1.4826 MAD): a few wild values (tracking failures) must not decide
// a correlation, and the clipped series stays continuous in the offset.
void winsorize(std::vector<double>& x) {
  if (x.size() < 5) return;
  const double med = median_of(x);
  std::vector<double> dev(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) dev[i] = std::abs(x[i] - med);
  const double s = std::max(1.4826 * median_of(dev), 1e-9);
  for (double& v : x) v = std::clamp(v, med - 3.0 * s, med + 3.0 * s);
}

// The vertex of the parabola through (−1, a), (0, b), (1, c), in steps, clamped to [−1, 1].
double parabola_vertex(double a, double b, double c) {
  const double den = a - 2.0 * b + c;
  if (std::abs(den) < 1e-30) return 0.0;
  return std::clamp(0.5 * (a - c) / den, -1.0, 1.0);
}

}  // namespace

TimeOffsetResult estimate_time_offset(const std::vector<VisualInterval>& visual, const std::vector<io::ImuSample>& imu,
                                      double centre_s, double range_s, double step_s, const Vector3d& bias) {
  TimeOffsetResult res;
  const int steps = static_cast<int>(std::ceil(range_s / step_s));
  // Intervals that the IMU covers at every candidate offset.
  std::vector<const VisualInterval*> used;
  std::vector<double> vis;
  for (const VisualInterval& v : visual) {
    if (!v.valid || v.t1 <= v.t0) continue;
    const TimeNs lo = v.t0 + from_seconds(centre_s - steps * step_s);
    const TimeNs hi = v.t1 + from_seconds(centre_s + steps * step_s);
    if (imu.empty() || imu.front().t > lo || imu.back().t < hi) continue;
    used.push_back(&v);
    vis.push_back(v.theta_C.norm() / to_seconds(v.t1 - v.t0));
  }
  res.intervals = static_cast<int>(used.size());
  if (used.size() < 10) return res;
  // The gyro's rate magnitudes at every candidate offset (intervals the IMU does not cover are NaN).
  const std::size_t nc = static_cast<std::size_t>(2 * steps + 1);
  std::vector<std::vector<double>> gyr(nc, std::vector<double>(used.size(), std::nan("")));
  for (int s = -steps; s <= steps; ++s) {
    const TimeNs d = from_seconds(centre_s + s * step_s);
    for (std::size_t i = 0; i < used.size(); ++i) {
      if (const auto th = integrate_gyro(imu, used[i]->t0 + d, used[i]->t1 + d, bias)) {
        gyr[static_cast<std::size_t>(s + steps)][i] = th->norm() / to_seconds(used[i]->t1 - used[i]->t0);
      }
    }
  }
  // Per candidate: the (winsorized) Pearson correlation, the quality figure; and the differences |ω_C| − |ω_R| less
  // their median (a gyro bias shifts the magnitudes), whose robust (Cauchy) cost locates the offset — a few wild
  // intervals (tracking failures) would decide a correlation.
  std::vector<double> corr(nc, -2.0), cost(nc, std::numeric_limits<double>::infinity());
  std::vector<std::vector<double>> resid(nc);
  for (std::size_t c = 0; c < nc; ++c) {
    std::vector<double> x, y;
    for (std::size_t i = 0; i < used.size(); ++i) {
      if (std::isnan(gyr[c][i])) continue;
      x.push_back(vis[i]);
      y.push_back(gyr[c][i]);
    }
    if (x.size() < 10) continue;
    std::vector<double> d(x.size());
    for (std::size_t i = 0; i < x.size(); ++i) d[i] = x[i] - y[i];
    const double med = median_of(d);
    for (double& v : d) v -= med;
    resid[c] = std::move(d);
    winsorize(x);
    winsorize(y);
    corr[c] = pearson(x, y);
  }
  const auto best_corr = std::max_element(corr.begin(), corr.end());
  if (*best_corr <= -1.5) return res;
  double scale = 0.0;
  {
    std::vector<double> a;
    for (double v : resid[static_cast<std::size_t>(best_corr - corr.begin())]) a.push_back(std::abs(v));
    scale = std::max(1.4826 * median_of(a), 0.005);
  }
  for (std::size_t c = 0; c < nc; ++c) {
    if (resid[c].empty()) continue;
    double sum = 0.0;
    for (double v : resid[c]) sum += std::log1p((v / scale) * (v / scale));
    cost[c] = sum / static_cast<double>(resid[c].size());
  }
  const auto best = std::min_element(cost.begin(), cost.end());
  const int ib = static_cast<int>(best - cost.begin());
  double frac = 0.0;
  if (ib > 0 && ib + 1 < static_cast<int>(nc) && std::isfinite(cost[static_cast<std::size_t>(ib - 1)]) &&
      std::isfinite(cost[static_cast<std::size_t>(ib + 1)])) {
    frac = parabola_vertex(cost[static_cast<std::size_t>(ib - 1)], *best, cost[static_cast<std::size_t>(ib + 1)]);
  }
  res.t_d_s = centre_s + (ib - steps + frac) * step_s;
  res.correlation = corr[static_cast<std::size_t>(ib)];
  // The correlation at the best other local minimum of the cost at least 4 steps away (an ambiguity figure).
  res.second_best = -1.0;
  double second_cost = std::numeric_limits<double>::infinity();
  for (int i = 1; i + 1 < static_cast<int>(nc); ++i) {
    const std::size_t u = static_cast<std::size_t>(i);
    if (std::abs(i - ib) >= 4 && cost[u] <= cost[u - 1] && cost[u] <= cost[u + 1] && cost[u] < second_cost) {
      second_cost = cost[u];
      res.second_best = corr[u];
    }
  }
  res.ok = true;
  return res;
}

std::optional<double> refine_time_offset(const std::vector<VisualInterval>& visual,
                                         const std::vector<io::ImuSample>& imu, const Matrix3d& R_RS,
                                         const Vector3d& bias, double centre_s, double range_s, double step_s) {
  const int steps = static_cast<int>(std::ceil(range_s / step_s));
  std::vector<const VisualInterval*> used;
  for (const VisualInterval& v : visual) {
    if (!v.valid || v.t1 <= v.t0) continue;
    if (imu.empty() || imu.front().t > v.t0 + from_seconds(centre_s - range_s - step_s) ||
        imu.back().t < v.t1 + from_seconds(centre_s + range_s + step_s)) {
      continue;
    }
    used.push_back(&v);
  }
  if (used.size() < 10) return std::nullopt;
  // A robust cost: each interval's residual rate, capped (a tracking failure must not pull the offset).
  std::vector<double> cost(static_cast<std::size_t>(2 * steps + 1), 0.0);
  for (int s = -steps; s <= steps; ++s) {
    const TimeNs d = from_seconds(centre_s + s * step_s);
    std::vector<double> r2;
    for (const VisualInterval* v : used) {
      const auto th = integrate_gyro(imu, v->t0 + d, v->t1 + d, bias);
      if (!th) return std::nullopt;
      const double dt = to_seconds(v->t1 - v->t0);
      r2.push_back(((*th - R_RS * v->theta_C) / dt).squaredNorm());
    }
    const double cap = 9.0 * std::max(median_of(r2), 1e-8);
    double c = 0.0;
    for (double x : r2) c += std::min(x, cap);
    cost[static_cast<std::size_t>(s + steps)] = c;
  }
  const auto best = std::min_element(cost.begin(), cost.end());
  const int ib = static_cast<int>(best - cost.begin());
  double frac = 0.0;
  if (ib > 0 && ib + 1 < static_cast<int>(cost.size())) {
    frac = parabola_vertex(cost[static_cast<std::size_t>(ib - 1)], *best, cost[static_cast<std::size_t>(ib + 1)]);
  }
  return centre_s + (ib - steps + frac) * step_s;
}

HandEyeResult estimate_hand_eye_rotation(const std::vector<Vector3d>& w_C, const std::vector<Vector3d>& w_R,
                                         const std::vector<double>& weights, double min_excitation_rad_s) {
  HandEyeResult res;
  const std::size_t n = std::min(w_C.size(), w_R.size());
  if (n < 8) return res;
  std::vector<double> w0(n, 1.0);
  for (std::size_t i = 0; i < n && i < weights.size(); ++i) w0[i] = std::max(weights[i], 0.0);
  // Excitation: the spread of the camera rates about their mean, along the second principal axis.
  {
    double sw = 0.0;
    Vector3d m = Vector3d::Zero();
    for (std::size_t i = 0; i < n; ++i) {
      sw += w0[i];
      m += w0[i] * w_C[i];
    }
    if (sw <= 0.0) return res;
    m /= sw;
    Matrix3d C = Matrix3d::Zero();
    for (std::size_t i = 0; i < n; ++i) C += w0[i] * (w_C[i] - m) * (w_C[i] - m).transpose();
    C /= sw;
    Eigen::SelfAdjointEigenSolver<Matrix3d> es(C);
    res.excitation_rad_s = std::sqrt(std::max(es.eigenvalues()(1), 0.0));
  }
  std::vector<double> w = w0;
  Matrix3d R = Matrix3d::Identity();
  Vector3d b = Vector3d::Zero();
  std::vector<Vector3d> a(n), c(n);
  double sigma = 0.0;
  for (int it = 0; it < 10; ++it) {
    double sw = 0.0;
    Vector3d mC = Vector3d::Zero(), mR = Vector3d::Zero();
    for (std::size_t i = 0; i < n; ++i) {
      sw += w[i];
      mC += w[i] * w_C[i];
      mR += w[i] * w_R[i];
    }
    if (sw <= 0.0) return res;
    mC /= sw;
    mR /= sw;
    for (std::size_t i = 0; i < n; ++i) {
      a[i] = w_R[i] - mR;
      c[i] = w_C[i] - mC;
    }
    R = kabsch(a, c, w);
    b = mR - R * mC;
    std::vector<double> r(n);
    for (std::size_t i = 0; i < n; ++i) r[i] = (w_R[i] - R * w_C[i] - b).norm();
    sigma = std::max(1.4826 * median_of(r), 1e-4);
    const double k = 2.5 * sigma;
    for (std::size_t i = 0; i < n; ++i) w[i] = w0[i] * (r[i] <= k ? 1.0 : k / r[i]);
  }
  double sw = 0.0, s2 = 0.0;
  Matrix3d H = Matrix3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const double ri = (w_R[i] - R * w_C[i] - b).norm();
    sw += w[i];
    s2 += w[i] * ri * ri;
    const Matrix3d S = math::skew(R * c[i]);
    H += w[i] * S.transpose() * S;
    res.used += w[i] > 0.5 * w0[i] && w0[i] > 0.0 ? 1 : 0;
  }
  res.R_RS = R;
  res.gyro_bias = b;
  res.rms_rad_s = sw > 0.0 ? std::sqrt(s2 / sw) : 0.0;
  // Per-component residual variance rms² / 3 through the information of the rotation (Gauss-Newton at the fit).
  Eigen::SelfAdjointEigenSolver<Matrix3d> es(H);
  const double lmin = es.eigenvalues()(0);
  res.rotation_std_deg = lmin > 1e-12 ? std::sqrt(res.rms_rad_s * res.rms_rad_s / 3.0 / lmin) * 180.0 / M_PI : 180.0;
  res.ok = res.excitation_rad_s >= min_excitation_rad_s && res.used >= 8;
  return res;
}

}  // namespace rtslam::calib
