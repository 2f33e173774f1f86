#include "rtslam/strategies/vi_init.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <optional>

#include <fmt/format.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/vision/harris.hpp"
#include "rtslam/vision/zncc.hpp"

namespace rtslam::strategies {

void ViInitOptions::validate() const {
  const std::string w = "imu/vi_init";
  require_bound(window_s > 0.0 && window_s <= 5.0, w, "window", window_s, "in (0, 5] s");
  require_bound(max_window_s >= window_s && max_window_s <= 10.0, w, "max_window", max_window_s,
                "in [window, 10] s");
  require_bound(min_excitation_m >= 0.0 && min_excitation_m < 10.0, w, "min_excitation_m", min_excitation_m,
                "in [0, 10) m");
  require_bound(max_wait_s >= 0.0 && max_wait_s <= 60.0, w, "max_wait", max_wait_s, "in [0, 60] s");
  require_bound(min_frames >= 3 && min_frames <= 500, w, "min_frames", min_frames, "in [3, 500]");
  require_bound(min_track_frames >= 3 && min_track_frames <= 500, w, "min_track_frames", min_track_frames,
                "in [3, 500]");
  require_bound(cells_x >= 1 && cells_x <= 64, w, "cells_x", cells_x, "in [1, 64]");
  require_bound(cells_y >= 1 && cells_y <= 64, w, "cells_y", cells_y, "in [1, 64]");
  require_bound(patch_size >= 5 && patch_size <= 41 && patch_size % 2 == 1, w, "patch_size", patch_size,
                "odd, in [5, 41]");
  require_bound(min_score > 0.0 && min_score < 1.0, w, "min_score", min_score, "in (0, 1)");
  require_bound(search_px >= 2.0 && search_px <= 200.0, w, "search_px", search_px, "in [2, 200] px");
  require_bound(min_features >= 4 && min_features <= 4096, w, "min_features", min_features, "in [4, 4096]");
  require_bound(standstill_max_disparity_px > 0.0 && standstill_max_disparity_px < 100.0, w,
                "standstill_max_disparity_px", standstill_max_disparity_px, "in (0, 100) px");
  require_bound(min_parallax_px > 0.0 && min_parallax_px < 1000.0, w, "min_parallax_px", min_parallax_px,
                "in (0, 1000) px");
  require_bound(max_reprojection_px > 0.0 && max_reprojection_px < 100.0, w, "max_reprojection_px",
                max_reprojection_px, "in (0, 100) px");
  require_bound(gravity > 1.0 && gravity < 30.0, w, "gravity", gravity, "in (1, 30) m/s²");
  require_bound(max_speed > 0.0 && max_speed <= 1e4, w, "max_speed", max_speed, "in (0, 1e4] m/s");
  require_bound(max_split_gravity_deg > 0.0 && max_split_gravity_deg <= 90.0, w, "max_split_gravity_deg",
                max_split_gravity_deg, "in (0, 90] deg");
  require_bound(max_split_velocity_ratio > 0.0 && max_split_velocity_ratio <= 10.0, w, "max_split_velocity_ratio",
                max_split_velocity_ratio, "in (0, 10]");
  require_bound(accel_bias_std > 0.0 && accel_bias_std <= 10.0, w, "accel_bias_std", accel_bias_std,
                "in (0, 10] m/s²");
}


using Eigen::Matrix3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

std::string ViInitResult::describe() const {
  switch (kind) {
    case Kind::Standstill:
      return fmt::format("visual standstill ({} features moved {:.2f} px over {} images)", features, disparity_px,
                         frames);
    case Kind::Dynamic:
      return fmt::format(
          "visual-inertial start in motion ({} features over {} images, parallax {:.1f} px, "
          "reprojection {:.2f} px, excitation {:.2f} m): |v0| = {:.3f} ± {:.3f} m/s, gravity ± {:.2f} deg, scene "
          "depth {:.2f} m",
          features, frames, parallax_px, reprojection_px, excitation_m, v0_R.norm(),
          std::sqrt(std::max(0.0, cov_v_g.topLeftCorner<3, 3>().trace())),
          std::sqrt(std::max(0.0, cov_v_g.bottomRightCorner<3, 3>().trace())) / std::max(1e-9, g_R.norm()) * 180.0 /
              M_PI,
          median_depth_m);
    case Kind::Failed:
      break;
  }
  return "visual-inertial start failed: " + reason;
}

namespace {

// Preintegrated IMU from t_0 to a frame time: R_{R0 Ri}, velocity and position increments without gravity and the
// initial velocity (specific force only).
struct Preint {
  Matrix3d dR = Matrix3d::Identity();
  Vector3d beta = Vector3d::Zero();
  Vector3d alpha = Vector3d::Zero();
  Matrix3d alpha_ba = Matrix3d::Zero();  // ∂alpha/∂(accelerometer bias)
  Matrix3d beta_ba = Matrix3d::Zero();   // ∂beta/∂(accelerometer bias)
  double dt = 0.0;
};

models::ImuMeasurement lerp(const ImuWindowSample& a, const ImuWindowSample& b, TimeNs t) {
  if (b.t == a.t) return a.m;
  const double s = static_cast<double>(t - a.t) / static_cast<double>(b.t - a.t);
  return {a.m.accel + s * (b.m.accel - a.m.accel), a.m.gyro + s * (b.m.gyro - a.m.gyro)};
}

// Midpoint integration over [t0, times.back()] with the gyro bias removed, recorded at each time. False if the IMU
// does not cover the span.
bool preintegrate(const std::vector<ImuWindowSample>& imu, TimeNs t0, const std::vector<TimeNs>& times,
                  const Vector3d& gyro_bias, std::vector<Preint>& out) {
  out.assign(times.size(), Preint{});
  if (imu.size() < 2 || imu.front().t > t0 || imu.back().t < times.back()) return false;
  std::size_t k = 0;
  while (k + 1 < imu.size() && imu[k + 1].t <= t0) ++k;
  Preint p;
  TimeNs t = t0;
  std::size_t next_frame = 0;
  while (next_frame < times.size() && times[next_frame] <= t0) out[next_frame++] = p;
  while (next_frame < times.size()) {
    while (k + 1 < imu.size() && imu[k + 1].t <= t) ++k;
    if (k + 1 >= imu.size()) return false;
    const TimeNs t1 = std::min(imu[k + 1].t, times[next_frame]);
    const models::ImuMeasurement m0 = lerp(imu[k], imu[k + 1], t);
    const models::ImuMeasurement m1 = lerp(imu[k], imu[k + 1], t1);
    const double dt = to_seconds(t1 - t);
    const Vector3d w = 0.5 * (m0.gyro + m1.gyro) - gyro_bias;
    const Matrix3d R1 = p.dR * math::exp_so3(w * dt).toRotationMatrix();
    const Vector3d a = 0.5 * (p.dR * m0.accel + R1 * m1.accel);
    const Matrix3d R_mid = 0.5 * (p.dR + R1);  // a = R_mid (m - b_a) for a constant bias
    p.alpha += p.beta * dt + 0.5 * a * dt * dt;
    p.beta += a * dt;
    p.alpha_ba += p.beta_ba * dt - 0.5 * R_mid * dt * dt;
    p.beta_ba -= R_mid * dt;
    p.dR = R1;
    p.dt += dt;
    t = t1;
    while (next_frame < times.size() && times[next_frame] <= t) out[next_frame++] = p;
  }
  return true;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace

ViInitResult initialize_visual_inertial(const std::vector<ViInitFrame>& frames, const std::vector<ImuWindowSample>& imu,
                                        const models::PinholeCamera& camera, const math::Pose& T_RS,
                                        const ViInitOptions& o) {
  ViInitResult res;
  res.frames = static_cast<int>(frames.size());
  if (static_cast<int>(frames.size()) < o.min_frames) {
    res.reason = fmt::format("{} images in the window, need {}", frames.size(), o.min_frames);
    return res;
  }
  const TimeNs t0 = frames.front().t;
  std::vector<TimeNs> times;
  for (const auto& f : frames) times.push_back(f.t);
  std::vector<Preint> pre;
  if (!preintegrate(imu, t0, times, Vector3d::Zero(), pre)) {
    res.reason = "the IMU does not cover the window";
    return res;
  }
  const Matrix3d R_RS = T_RS.q.toRotationMatrix();
  const Matrix3d R_SR = R_RS.transpose();
  const Vector3d t_SR = -R_SR * T_RS.p;

  // 1. Features: the best Harris corner of each empty grid cell, tracked image to image; a track may begin in any
  // image of the window and end where its feature leaves the view (at 400 deg/s a corner crosses the image in a
  // fifth of a second, so hardly any survives a whole window), and cells emptied by the motion are refilled.
  const models::CameraIntrinsics& in = camera.intrinsics();
  const int half = o.patch_size / 2;
  vision::HarrisDetector harris;
  vision::ZnccOptions zo;
  zo.patch_size = o.patch_size;
  zo.threshold = o.min_score;
  vision::ZnccMatcher matcher(zo);
  const std::size_t n_frames = frames.size();
  const std::size_t min_track = static_cast<std::size_t>(std::min<int>(o.min_track_frames, static_cast<int>(n_frames)));
  struct Track {
    std::size_t first = 0;       // image of px[0]
    std::vector<Vector2d> px;    // px[k]: in image first + k
    vision::Patch patch;         // the last image's patch (the template of the next match)
    bool alive = true;
    bool seen(std::size_t i) const { return i >= first && i < first + px.size(); }
    const Vector2d& at(std::size_t i) const { return px[i - first]; }
    std::size_t end() const { return first + px.size(); }
  };
  std::vector<Track> tracks;
  const int border = half + 2;
  const auto cell_of = [&](const Vector2d& px) {
    const int cx = std::clamp(static_cast<int>((px.x() - border) * o.cells_x / (in.width - 2 * border)), 0, o.cells_x - 1);
    const int cy =
        std::clamp(static_cast<int>((px.y() - border) * o.cells_y / (in.height - 2 * border)), 0, o.cells_y - 1);
    return cy * o.cells_x + cx;
  };
  std::vector<char> occupied(static_cast<std::size_t>(o.cells_x * o.cells_y));
  for (std::size_t i = 0; i < n_frames; ++i) {
    const vision::ImageView vi = frames[i].image;
    if (i > 0) {
      // Rotation of camera i-1 into camera i from the gyro: R_{Ci C(i-1)} = R_SR ΔR_iᵀ ΔR_{i-1} R_RS.
      const Matrix3d R_ci_cp = R_SR * pre[i].dR.transpose() * pre[i - 1].dR * R_RS;
      for (Track& t : tracks) {
        if (!t.alive) continue;
        Vector3d ray;
        Vector2d pred;
        if (!camera.unproject(t.px.back(), ray) || !camera.project(R_ci_cp * ray, pred) ||
            !camera.in_image(pred, half)) {
          t.alive = false;
          ++res.tracks_left_view;
          continue;
        }
        const vision::MatchResult m =
            matcher.match(t.patch, vi, vision::SearchEllipse::box(pred, o.search_px, o.search_px));
        if (!m.found || !t.patch.extract(vi, m.u_px, m.v_px, o.patch_size) || t.patch.centred_energy() <= 0) {
          t.alive = false;
          ++res.tracks_unmatched;
          continue;
        }
        t.px.emplace_back(m.u, m.v);
      }
    }
    // New tracks in the empty cells, while they can still reach min_track_frames images.
    if (i + min_track > n_frames) continue;
    std::fill(occupied.begin(), occupied.end(), 0);
    for (const Track& t : tracks)
      if (t.alive) occupied[static_cast<std::size_t>(cell_of(t.px.back()))] = 1;
    for (int cy = 0; cy < o.cells_y; ++cy) {
      for (int cx = 0; cx < o.cells_x; ++cx) {
        if (occupied[static_cast<std::size_t>(cy * o.cells_x + cx)]) continue;
        const auto c =
            harris.best_corner(vi, vision::grid_cell(in.width, in.height, border, o.cells_x, o.cells_y, cx, cy));
        if (!c) continue;
        Track t;
        t.first = i;
        if (!t.patch.extract(vi, c->u_px, c->v_px, o.patch_size) || t.patch.centred_energy() <= 0) continue;
        t.px.emplace_back(c->u_px, c->v_px);
        tracks.push_back(std::move(t));
      }
    }
  }
  std::erase_if(tracks, [&](const Track& t) { return t.px.size() < min_track; });
  res.features = static_cast<int>(tracks.size());
  if (res.features < o.min_features) {
    res.reason = fmt::format("{} features tracked over {} images or more, need {} ({} tracks left the view, {} lost "
                             "their match)",
                             res.features, min_track, o.min_features, res.tracks_left_view, res.tracks_unmatched);
    return res;
  }
  // Disparity (raw) and parallax (rotation removed) between each track's first and last image; at rest every
  // feature stays in view, so the disparity is taken over the tracks spanning the whole window.
  std::vector<double> disp, disp_full, para;
  for (const Track& t : tracks) {
    disp.push_back((t.px.back() - t.px.front()).norm());
    if (t.first == 0 && t.end() == n_frames) disp_full.push_back(disp.back());
    const Matrix3d R_cl_cf = R_SR * pre[t.end() - 1].dR.transpose() * pre[t.first].dR * R_RS;
    Vector3d ray;
    Vector2d derot;
    if (camera.unproject(t.px.front(), ray) && camera.project(R_cl_cf * ray, derot)) {
      para.push_back((t.px.back() - derot).norm());
    }
  }
  const bool enough_full = static_cast<int>(disp_full.size()) >= o.min_features;
  res.disparity_px = median(enough_full ? disp_full : disp);
  res.parallax_px = median(para);

  // 2. At rest: the images say so, whatever the IMU's vibration.
  if (enough_full && res.disparity_px < o.standstill_max_disparity_px) {
    Vector3d mw = Vector3d::Zero(), ma = Vector3d::Zero();
    int n = 0;
    for (const auto& s : imu) {
      if (s.t < t0 || s.t > times.back()) continue;
      mw += s.m.gyro;
      ma += s.m.accel;
      ++n;
    }
    if (n < 2) {
      res.reason = "no IMU sample in the window";
      return res;
    }
    res.kind = ViInitResult::Kind::Standstill;
    res.gyro_bias = mw / n;
    res.g_R = -ma / n;
    return res;
  }
  if (res.parallax_px < o.min_parallax_px) {
    res.reason = fmt::format("median parallax {:.1f} px below {:.1f} px (rotation without enough translation)",
                             res.parallax_px, o.min_parallax_px);
    res.needs_longer_window = true;
    return res;
  }

  // 3. Linear least squares: features eliminated, g on the sphere, then v0 and the features. Features whose
  // reprojection error stands out (tracking slips) are dropped and the problem solved again.
  // One observation: rows A p_f + B θ = c with A = [b]× R_SR ΔR_iᵀ, B = [−A t_i, −½ A t_i²], c = A α_i − [b]× t_SR.
  const auto rows = [&](const Track& t, std::size_t i, Matrix3d& A, Eigen::Matrix<double, 3, 6>& B, Vector3d& c) {
    Vector3d ray;
    if (!t.seen(i) || !camera.unproject(t.at(i), ray)) return false;
    const Matrix3d bx = math::skew(ray.normalized());
    A = bx * R_SR * pre[i].dR.transpose();
    const double dt = pre[i].dt;
    B.leftCols<3>() = -A * dt;
    B.rightCols<3>() = -0.5 * A * dt * dt;
    c = A * pre[i].alpha - bx * t_SR;
    return true;
  };
  struct Solution {
    bool ok = false;
    std::string reason;
    Vector3d v0 = Vector3d::Zero(), g = Vector3d::Zero();
    std::vector<double> rms_px;    // per feature of the subset
    std::vector<double> depth;     // per feature: distance from camera 0 (NaN behind a camera)
    Eigen::VectorXd residual;      // the stacked rows A p_f + B θ − c (weighted)
    std::vector<double> range;     // per (feature, image): distance of the feature from the camera (NaN: none)
    std::vector<Vector3d> points;  // per feature: position in R_0
  };
  // weights (optional, per (feature, image)): 1 / the feature's distance, so that the rows measure angles, not
  // angles times distances (the unweighted problem favours shrinking the scene).
  const auto solve = [&](const std::vector<int>& subset, std::size_t i_begin, std::size_t i_end,
                         const std::vector<double>* weights) {
    Solution sol;
    const auto weight = [&](std::size_t j, std::size_t i) {
      if (weights == nullptr) return 1.0;
      const double w = (*weights)[j * n_frames + i];
      return std::isfinite(w) && w > 0.0 ? w : 1.0;
    };
    struct FeatureBlocks {
      Matrix3d U = Matrix3d::Zero();
      Eigen::Matrix<double, 3, 6> W = Eigen::Matrix<double, 3, 6>::Zero();
      Vector3d a = Vector3d::Zero();
    };
    std::vector<FeatureBlocks> fb(subset.size());
    Eigen::Matrix<double, 6, 6> V = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    // A feature seen fewer than twice in [i_begin, i_end) has no position: it stays out of the problem.
    const auto span = [&](const Track& t) {
      return std::pair<std::size_t, std::size_t>{std::max(i_begin, t.first), std::min(i_end, t.end())};
    };
    std::vector<char> used(subset.size(), 0);
    for (std::size_t j = 0; j < subset.size(); ++j) {
      const Track& t = tracks[static_cast<std::size_t>(subset[j])];
      const auto [ib, ie] = span(t);
      if (ie < ib + 2) continue;
      used[j] = 1;
      for (std::size_t i = ib; i < ie; ++i) {
        Matrix3d A;
        Eigen::Matrix<double, 3, 6> B;
        Vector3d c;
        if (!rows(t, i, A, B, c)) continue;
        const double w = weight(j, i);
        A *= w;
        B *= w;
        c *= w;
        fb[j].U += A.transpose() * A;
        fb[j].W += A.transpose() * B;
        fb[j].a += A.transpose() * c;
        V += B.transpose() * B;
        b += B.transpose() * c;
      }
    }
    Eigen::Matrix<double, 6, 6> S = V;
    Eigen::Matrix<double, 6, 1> s = b;
    for (const auto& f : fb) {
      if (f.U.isZero()) continue;
      const Eigen::LDLT<Matrix3d> U(f.U);
      if (U.info() != Eigen::Success || !(U.vectorD().minCoeff() > 1e-12)) continue;
      S -= f.W.transpose() * U.solve(f.W);
      s -= f.W.transpose() * U.solve(f.a);
    }
    const Matrix3d Svv = S.topLeftCorner<3, 3>(), Svg = S.topRightCorner<3, 3>(), Sgg = S.bottomRightCorner<3, 3>();
    const Eigen::LDLT<Matrix3d> Lvv(Svv);
    const Matrix3d M = Sgg - Svg.transpose() * Lvv.solve(Svg);
    const Vector3d e = s.tail<3>() - Svg.transpose() * Lvv.solve(s.head<3>());
    // g on the sphere: (M + λI) g = e with |g| = gravity, λ > −σ_min (trust-region subproblem, bisection on λ).
    const Eigen::SelfAdjointEigenSolver<Matrix3d> es(0.5 * (M + M.transpose()));
    const Vector3d sig = es.eigenvalues();
    const Vector3d ue = es.eigenvectors().transpose() * e;
    const auto g_of = [&](double lambda) {
      Vector3d c;
      for (int k = 0; k < 3; ++k) c[k] = ue[k] / (sig[k] + lambda);
      return Vector3d(es.eigenvectors() * c);
    };
    double lo = -sig[0] + 1e-12 * std::max(1.0, std::abs(sig[0])), hi = e.norm() / o.gravity + std::abs(sig[0]) + 1.0;
    for (int it = 0; it < 200; ++it) {
      const double mid = 0.5 * (lo + hi);
      (g_of(mid).norm() > o.gravity ? lo : hi) = mid;
    }
    sol.g = g_of(0.5 * (lo + hi)).normalized() * o.gravity;
    sol.v0 = Lvv.solve(s.head<3>() - Svg * sol.g);
    if (!sol.g.allFinite() || !sol.v0.allFinite()) {
      sol.reason = "the linear system is degenerate";
      return sol;
    }
    Eigen::Matrix<double, 6, 1> theta;
    theta << sol.v0, sol.g;
    sol.residual.setZero(3 * static_cast<Eigen::Index>(subset.size() * n_frames));
    sol.range.assign(subset.size() * n_frames, std::numeric_limits<double>::quiet_NaN());
    Eigen::Index rr = 0;
    for (std::size_t j = 0; j < subset.size(); ++j) {
      const Track& t = tracks[static_cast<std::size_t>(subset[j])];
      if (!used[j]) {
        sol.points.push_back(Vector3d::Zero());
        sol.rms_px.push_back(std::numeric_limits<double>::quiet_NaN());
        sol.depth.push_back(std::numeric_limits<double>::quiet_NaN());
        continue;
      }
      const Vector3d p_f = Eigen::LDLT<Matrix3d>(fb[j].U).solve(fb[j].a - fb[j].W * theta);
      sol.points.push_back(p_f);
      double sse = 0.0;
      int n = 0;
      double depth = std::numeric_limits<double>::quiet_NaN();
      bool front = true;
      const auto [ib, ie] = span(t);
      rr = 3 * static_cast<Eigen::Index>(j * n_frames + ib);
      for (std::size_t i = ib; i < ie; ++i) {
        const double dt = pre[i].dt;
        const Vector3d p_C =
            R_SR * (pre[i].dR.transpose() * (p_f - sol.v0 * dt - 0.5 * sol.g * dt * dt - pre[i].alpha)) + t_SR;
        Matrix3d A;
        Eigen::Matrix<double, 3, 6> B;
        Vector3d c;
        if (rows(t, i, A, B, c)) {
          const Vector3d r = weight(j, i) * (A * p_f + B * theta - c);
          sol.residual.segment<3>(rr) = r;
        }
        rr += 3;
        Vector2d z;
        if (!(p_C.z() > 0.0) || !camera.project(p_C, z)) {
          front = false;
          continue;
        }
        sol.range[j * n_frames + i] = p_C.norm();
        sse += (z - t.at(i)).squaredNorm();
        ++n;
        if (i == ib) depth = p_C.norm();
      }
      sol.rms_px.push_back(front && n > 0 ? std::sqrt(sse / n) : std::numeric_limits<double>::infinity());
      sol.depth.push_back(front ? depth : std::numeric_limits<double>::quiet_NaN());
    }
    sol.ok = true;
    return sol;
  };
  // Reweighted: solved once unweighted, then twice with the weights of the previous solution's distances.
  const auto solve_irls = [&](const std::vector<int>& subset, std::size_t i_begin, std::size_t i_end) {
    Solution sol = solve(subset, i_begin, i_end, nullptr);
    std::vector<double> w;
    for (int round = 0; round < 2 && sol.ok; ++round) {
      w.assign(sol.range.size(), 0.0);
      for (std::size_t k = 0; k < w.size(); ++k) {
        w[k] = std::isfinite(sol.range[k]) ? 1.0 / std::clamp(sol.range[k], 0.1, 100.0) : 0.0;
      }
      sol = solve(subset, i_begin, i_end, &w);
    }
    return sol;
  };
  std::vector<int> subset(static_cast<std::size_t>(res.features));
  for (int f = 0; f < res.features; ++f) subset[static_cast<std::size_t>(f)] = f;
  // The gyro bias: real IMUs carry several deg/s (EuRoC's ADIS16448: 0.08 rad/s about one axis), which bends every
  // derotated bearing of the window. Gauss-Newton on the three bias components (numerical Jacobians) of the stacked
  // algebraic residuals, the linear problem solved anew inside (variable projection).
  Vector3d b_g = Vector3d::Zero();
  {
    const auto residual_at = [&](const Vector3d& b) -> std::optional<Eigen::VectorXd> {
      if (!preintegrate(imu, t0, times, b, pre)) return std::nullopt;
      Solution sl = solve_irls(subset, 0, frames.size());
      if (!sl.ok) return std::nullopt;
      return sl.residual;
    };
    for (int it = 0; it < 8; ++it) {
      const auto r0 = residual_at(b_g);
      if (!r0) break;
      Eigen::Matrix<double, Eigen::Dynamic, 3> J(r0->size(), 3);
      bool ok = true;
      for (int k = 0; k < 3; ++k) {
        const double h = 1e-4;
        const auto rk = residual_at(b_g + h * Vector3d::Unit(k));
        if (!rk) {
          ok = false;
          break;
        }
        J.col(k) = (*rk - *r0) / h;
      }
      if (!ok) break;
      const Eigen::Matrix3d JtJ = J.transpose() * J;
      const Vector3d step = -JtJ.ldlt().solve(J.transpose() * *r0);
      if (!step.allFinite()) break;
      // Accept the step only if it lowers the cost (halving it otherwise).
      double scale = 1.0;
      bool better = false;
      for (int h = 0; h < 6 && !better; ++h, scale *= 0.5) {
        const auto r1 = residual_at(b_g + scale * step);
        if (r1 && r1->squaredNorm() < r0->squaredNorm()) {
          b_g += scale * step;
          better = true;
        }
      }
      if (!better || (scale * step).norm() < 1e-6) break;
    }
    if (!(b_g.norm() < 1.0)) b_g.setZero();  // rad/s: implausible, keep none
    preintegrate(imu, t0, times, b_g, pre);
  }
  res.gyro_bias = b_g;
  Solution sol;
  for (int round = 0; round < 4; ++round) {
    sol = solve_irls(subset, 0, frames.size());
    if (!sol.ok) {
      res.reason = sol.reason;
      return res;
    }
    const double bound = std::max(3.0 * median(sol.rms_px), 0.5 * o.max_reprojection_px);
    std::vector<int> kept;
    for (std::size_t j = 0; j < subset.size(); ++j)
      if (sol.rms_px[j] <= bound) kept.push_back(subset[j]);
    if (kept.size() == subset.size()) break;
    if (static_cast<int>(kept.size()) < o.min_features) {
      res.reason = fmt::format("{} of {} features consistent with one motion, need {}", kept.size(), subset.size(),
                               o.min_features);
      return res;
    }
    subset = std::move(kept);
  }
  res.features = static_cast<int>(subset.size());
  // 4. Maximum likelihood: the linear solution minimizes algebraic errors (cross products), which are not the
  // pixel errors: it biases the scale low on real tracks and, at 400 deg/s, tilts gravity by 10-20 deg where the
  // pixel errors say 1 deg. It starts a robust Gauss-Newton (Levenberg-Marquardt) on the reprojection errors over
  // v0, gravity (on its sphere), the accelerometer bias (with its prior: over a short window it is nearly
  // indistinguishable from a tilt), the gyro bias (its change from step 3's estimate, preintegration Jacobians
  // taken numerically) and the features (eliminated by Schur complement), as the refinement step of the OpenVINS and
  // VINS-Mono initializers. It is run on the whole window and, for the consistency check, on its two parts.
  using Mat11 = Eigen::Matrix<double, 11, 11>;
  using Vec11 = Eigen::Matrix<double, 11, 1>;
  struct Refined {
    Vector3d v0 = Vector3d::Zero(), g = Vector3d::Zero(), b_a = Vector3d::Zero(), b_g = Vector3d::Zero();
    std::vector<Vector3d> pts;
    Mat11 H = Mat11::Identity();    // reduced information of [v0 δg b_a b_g] (unit pixel noise)
    std::vector<double> rms_px;     // per feature of the subset (∞: behind a camera, NaN: not in the range)
    std::vector<double> depth;      // per feature: distance from the camera of its first image in the range
    std::vector<double> sq;         // every squared pixel residual
  };
  const double huber = 1.5;                                             // px
  const double prior_ba = 1.0 / (o.accel_bias_std * o.accel_bias_std);  // (m/s²)⁻², per axis
  const auto tangent = [](const Vector3d& gv) {
    Eigen::Matrix<double, 3, 2> T;
    const Vector3d nv = gv.normalized();
    const Vector3d av = std::abs(nv.x()) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY();
    T.col(0) = nv.cross(av).normalized();
    T.col(1) = nv.cross(T.col(0));
    return T;
  };
  const auto refine = [&](std::size_t i_begin, std::size_t i_end, Refined x, bool with_gyro_bias) {
    const std::size_t m = subset.size();
    std::vector<char> used(m, 0);
    for (std::size_t j = 0; j < m; ++j) {
      const Track& t = tracks[static_cast<std::size_t>(subset[j])];
      used[j] = std::min(i_end, t.end()) >= std::max(i_begin, t.first) + 2 ? 1 : 0;
    }
    std::vector<Preint> pr;
    preintegrate(imu, t0, times, x.b_g, pr);
    // Pixel residual of feature j in image i, and its Jacobians (false: behind the camera or outside the model).
    // J_bg: the rotation ΔR_i(b_g + δ) ≈ ΔR_i Exp(JR_i δ) and α_i(b_g + δ) ≈ α_i + JA_i δ.
    std::vector<Matrix3d> JR(n_frames, Matrix3d::Zero()), JA(n_frames, Matrix3d::Zero());
    const auto residual = [&](std::size_t j, std::size_t i, const std::vector<Preint>& pi, const Vector3d& pv,
                              const Vector3d& vv, const Vector3d& gv, const Vector3d& bv, Vector2d& r,
                              Eigen::Matrix<double, 2, 3>* Jp, Eigen::Matrix<double, 2, 11>* Jt) {
      const Track& t = tracks[static_cast<std::size_t>(subset[j])];
      if (!t.seen(i)) return false;
      const double dt = pi[i].dt;
      const Vector3d q = pv - vv * dt - 0.5 * gv * dt * dt - pi[i].alpha + pi[i].alpha_ba * bv;
      const Matrix3d C = R_SR * pi[i].dR.transpose();
      const Vector3d p_C = C * q + t_SR;
      if (!(p_C.z() > 0.05)) return false;
      Vector2d z;
      Eigen::Matrix<double, 2, 3> J_pi;
      if (!camera.project(p_C, z, &J_pi)) return false;
      r = z - t.at(i);
      if (Jp != nullptr) {
        const Eigen::Matrix<double, 2, 3> JC = J_pi * C;
        *Jp = JC;
        Jt->leftCols<3>() = -dt * JC;
        Jt->middleCols<2>(3) = -0.5 * dt * dt * o.gravity * JC * tangent(gv);
        Jt->middleCols<3>(5) = JC * pi[i].alpha_ba;
        Jt->rightCols<3>() = J_pi * R_SR * (math::skew(pi[i].dR.transpose() * q) * JR[i] - pi[i].dR.transpose() * JA[i]);
      }
      return true;
    };
    const auto cost = [&](const std::vector<Preint>& pi, const Refined& y) {
      double c = prior_ba * y.b_a.squaredNorm();
      for (std::size_t j = 0; j < m; ++j) {
        if (!used[j]) continue;
        for (std::size_t i = i_begin; i < i_end; ++i) {
          Vector2d r;
          if (!residual(j, i, pi, y.pts[j], y.v0, y.g, y.b_a, r, nullptr, nullptr)) continue;
          const double e = r.norm();
          c += e <= huber ? e * e : huber * (2.0 * e - huber);
        }
      }
      return c;
    };
    double c0 = cost(pr, x);
    double lambda = 1e-4;
    const int n_theta = with_gyro_bias ? 11 : 8;
    for (int it = 0; it < 15 && std::isfinite(c0); ++it) {
      if (with_gyro_bias) {
        for (int k = 0; k < 3; ++k) {
          const double h = 1e-5;
          std::vector<Preint> pk;
          preintegrate(imu, t0, times, x.b_g + h * Vector3d::Unit(k), pk);
          for (std::size_t i = 0; i < n_frames; ++i) {
            JR[i].col(k) = math::log_so3(Eigen::Quaterniond(pr[i].dR.transpose() * pk[i].dR)) / h;
            JA[i].col(k) = (pk[i].alpha - pr[i].alpha) / h;
          }
        }
      }
      Mat11 V = Mat11::Zero();
      Vec11 bvec = Vec11::Zero();
      V.block<3, 3>(5, 5) += prior_ba * Matrix3d::Identity();
      bvec.segment<3>(5) -= prior_ba * x.b_a;
      std::vector<Matrix3d> U(m, Matrix3d::Zero());
      std::vector<Eigen::Matrix<double, 3, 11>> Wm(m, Eigen::Matrix<double, 3, 11>::Zero());
      std::vector<Vector3d> up(m, Vector3d::Zero());
      for (std::size_t j = 0; j < m; ++j) {
        if (!used[j]) continue;
        for (std::size_t i = i_begin; i < i_end; ++i) {
          Vector2d r;
          Eigen::Matrix<double, 2, 3> Jp;
          Eigen::Matrix<double, 2, 11> Jt;
          if (!residual(j, i, pr, x.pts[j], x.v0, x.g, x.b_a, r, &Jp, &Jt)) continue;
          const double e = r.norm();
          const double w = e <= huber ? 1.0 : huber / e;
          U[j] += w * Jp.transpose() * Jp;
          Wm[j] += w * Jp.transpose() * Jt;
          up[j] -= w * Jp.transpose() * r;
          V += w * Jt.transpose() * Jt;
          bvec -= w * Jt.transpose() * r;
        }
      }
      Mat11 S = V;
      Vec11 sv = bvec;
      std::vector<Matrix3d> Uinv(m, Matrix3d::Zero());
      for (std::size_t j = 0; j < m; ++j) {
        if (!used[j]) continue;
        Uinv[j] = (U[j] + lambda * Matrix3d(U[j].diagonal().asDiagonal()) + 1e-9 * Matrix3d::Identity()).inverse();
        S -= Wm[j].transpose() * Uinv[j] * Wm[j];
        sv -= Wm[j].transpose() * Uinv[j] * up[j];
      }
      if (!with_gyro_bias) {  // b_g held: its rows and columns out of the step
        S.bottomRows<3>().setZero();
        S.rightCols<3>().setZero();
        S.bottomRightCorner<3, 3>().setIdentity();
        sv.tail<3>().setZero();
      }
      x.H = S;
      const Vec11 step = (S + lambda * Mat11(S.diagonal().asDiagonal())).ldlt().solve(sv);
      if (!step.allFinite()) break;
      Refined y = x;
      for (std::size_t j = 0; j < m; ++j)
        if (used[j]) y.pts[j] = x.pts[j] + Uinv[j] * (up[j] - Wm[j] * step);
      y.v0 = x.v0 + step.head<3>();
      y.g = (x.g + tangent(x.g) * step.segment<2>(3) * o.gravity).normalized() * o.gravity;
      y.b_a = x.b_a + step.segment<3>(5);
      y.b_g = x.b_g + step.tail<3>();
      std::vector<Preint> py;
      if (n_theta == 11) {
        preintegrate(imu, t0, times, y.b_g, py);
      } else {
        py = pr;
      }
      const double c1 = cost(py, y);
      if (c1 < c0) {
        const double gain = c0 - c1;
        x = std::move(y);
        pr = std::move(py);
        c0 = c1;
        lambda = std::max(1e-7, lambda / 10.0);
        if (gain < 1e-6 * c0 || step.norm() < 1e-7) break;
      } else {
        lambda *= 10.0;
        if (lambda > 1e4) break;
      }
    }
    // Per-feature RMS, and depth in the camera of the feature's first image in the range.
    x.rms_px.assign(m, std::numeric_limits<double>::quiet_NaN());
    x.depth.assign(m, std::numeric_limits<double>::quiet_NaN());
    x.sq.clear();
    for (std::size_t j = 0; j < m; ++j) {
      if (!used[j]) continue;
      const Track& t = tracks[static_cast<std::size_t>(subset[j])];
      double sse = 0.0;
      int n = 0;
      bool front = true;
      const std::size_t ib = std::max(i_begin, t.first), ie = std::min(i_end, t.end());
      for (std::size_t i = ib; i < ie; ++i) {
        Vector2d r;
        if (!residual(j, i, pr, x.pts[j], x.v0, x.g, x.b_a, r, nullptr, nullptr)) {
          front = false;
          continue;
        }
        sse += r.squaredNorm();
        x.sq.push_back(r.squaredNorm());
        ++n;
      }
      x.rms_px[j] = front && n > 0 ? std::sqrt(sse / n) : std::numeric_limits<double>::infinity();
      if (front && n > 0) {
        const Preint& p0 = pr[ib];
        const double dt = p0.dt;
        x.depth[j] = (R_SR * p0.dR.transpose() *
                          (x.pts[j] - x.v0 * dt - 0.5 * x.g * dt * dt - p0.alpha + p0.alpha_ba * x.b_a) +
                      t_SR)
                         .norm();
      }
    }
    return x;
  };
  Refined start;
  start.v0 = sol.v0;
  start.g = sol.g;
  start.b_g = b_g;
  start.pts = sol.points;
  const Refined ml = refine(0, n_frames, start, o.refine_gyro_bias);
  const Vector3d v0 = ml.v0, g = ml.g;
  sol.rms_px = ml.rms_px;
  sol.depth = ml.depth;
  {
    // Covariance of [v0 δg b_a]: the reduced information with the tracking noise (the median squared residual per
    // axis, at least (0.5 px)²), gravity mapped back to 3D; kept in the result for the filter's prior.
    const double sigma2 = std::max(0.25, 0.5 * median(ml.sq) / 0.4549);  // median of χ²₂ is 1.386; per axis
    const Mat11 cov11 = sigma2 * ml.H.ldlt().solve(Mat11::Identity());
    Eigen::Matrix<double, 6, 11> M = Eigen::Matrix<double, 6, 11>::Zero();
    M.topLeftCorner<3, 3>().setIdentity();
    M.block<3, 2>(3, 3) = o.gravity * tangent(g);
    res.cov_v_g = M * cov11 * M.transpose();
    if (o.refine_gyro_bias) res.cov_gyro_bias = cov11.bottomRightCorner<3, 3>();
    res.accel_bias = ml.b_a;
    res.gyro_bias = ml.b_g;
    preintegrate(imu, t0, times, ml.b_g, pre);
  }
  // The scale comes from the accelerations: their displacement over the window, |α_i + ½ g t_i²| (R_0), must stand
  // out of the tracking noise and the unmodelled accelerometer bias (½ b t² is 8 mm over 0.4 s for 0.1 m/s²).
  double excitation = 0.0;
  for (std::size_t i = 0; i < frames.size(); ++i)
    excitation = std::max(excitation, (pre[i].alpha + 0.5 * g * pre[i].dt * pre[i].dt).norm());
  res.excitation_m = excitation;
  if (excitation < o.min_excitation_m) {
    res.reason = fmt::format(
        "acceleration displaces the body by {:.3f} m over the window, below {:.3f} m (scale "
        "not observable yet)",
        excitation, o.min_excitation_m);
    res.needs_longer_window = true;
    return res;
  }
  if (v0.norm() > o.max_speed) {
    res.reason = fmt::format("|v0| = {:.1f} m/s above max_speed", v0.norm());
    return res;
  }
  double sse_px = 0.0;
  int n_px = 0;
  std::vector<double> depths;
  for (std::size_t j = 0; j < subset.size(); ++j) {
    if (!std::isfinite(sol.rms_px[j])) continue;
    sse_px += sol.rms_px[j] * sol.rms_px[j];
    ++n_px;
    if (std::isfinite(sol.depth[j])) depths.push_back(sol.depth[j]);
  }
  res.reprojection_px = n_px > 0 ? std::sqrt(sse_px / n_px) : 0.0;
  // Self-consistency: the first and the last two thirds of the window, solved apart for the same unknowns (v0 and g
  // at the first image, in R_0), must agree. A window whose tracks drift consistently (fast rotation) can fit one
  // wrong motion to a pixel; its parts then disagree.
  const std::size_t n = frames.size();
  // The parts keep the whole window's gyro bias: they check the motion (v0, g), and a third less data would leave the
  // bias free to absorb their differences.
  const Refined early = refine(0, (2 * n + 2) / 3, ml, false), late = refine(n / 3, n, ml, false);
  // All three (the whole window and its parts) must agree: parts that agree with each other but not with the whole
  // say that the whole window's refinement stopped in a local minimum of the linear solution's making.
  const auto angle_deg = [](const Vector3d& a, const Vector3d& b) {
    return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
  };
  const double g_angle = std::max({angle_deg(early.g, late.g), angle_deg(g, early.g), angle_deg(g, late.g)});
  const double dv = std::max({(early.v0 - late.v0).norm(), (v0 - early.v0).norm(), (v0 - late.v0).norm()});
  if (g_angle > o.max_split_gravity_deg || dv > 0.05 + o.max_split_velocity_ratio * v0.norm()) {
    res.reason =
        fmt::format("the window's parts disagree (gravity {:.1f} deg, velocity {:.2f} m/s apart)", g_angle, dv);
    res.needs_longer_window = true;  // a longer window conditions the problem better
    return res;
  }
  if (n_px < std::max(o.min_features, (3 * static_cast<int>(subset.size())) / 4)) {
    res.reason = fmt::format("only {} of {} features in front of the cameras", n_px, subset.size());
    return res;
  }
  if (!(res.reprojection_px <= o.max_reprojection_px)) {
    res.reason = fmt::format("reprojection RMS {:.2f} px above {:.2f} px", res.reprojection_px, o.max_reprojection_px);
    return res;
  }
  res.kind = ViInitResult::Kind::Dynamic;
  res.v0_R = v0;
  res.g_R = g;
  res.median_depth_m = median(depths);
  return res;
}

InertialStart inertial_start_from_vi(const ViInitResult& r, const InertialStartOptions& o) {
  RTSLAM_CHECK(r.kind != ViInitResult::Kind::Failed, "inertial_start_from_vi: the start failed");
  using I = models::InertialIndex;
  InertialStart s;
  s.standstill = r.kind == ViInitResult::Kind::Standstill;
  const Eigen::Quaterniond q_WR = gravity_aligned_attitude(-r.g_R);
  const Matrix3d R = q_WR.toRotationMatrix();
  s.x.segment<4>(I::kQ) = math::quat_to_wxyz(q_WR);
  s.x.segment<3>(I::kG) = R * r.g_R;
  if (s.standstill) {
    s.x.segment<3>(I::kWb) = r.gyro_bias;
    s.P = prior_covariance(o.velocity_std_standstill, o.accel_bias_std, 1e-3, o.gravity_std_standstill, R);
    constrain_gravity_magnitude(s, o);
    return s;
  }
  s.x.segment<3>(I::kV) = R * r.v0_R;
  s.x.segment<3>(I::kWb) = r.gyro_bias;
  s.x.segment<3>(I::kAb) = r.accel_bias;
  const Eigen::SelfAdjointEigenSolver<Matrix3d> ev(r.cov_v_g.topLeftCorner<3, 3>());
  const Eigen::SelfAdjointEigenSolver<Matrix3d> eg(r.cov_v_g.bottomRightCorner<3, 3>());
  const double v_std = std::max(0.05, 3.0 * std::sqrt(std::max(0.0, ev.eigenvalues().maxCoeff())));
  const double g_std = std::max(0.1, 3.0 * std::sqrt(std::max(0.0, eg.eigenvalues().maxCoeff())));
  // The gyro bias as the window estimated it: the filter's prior, or the estimate's 3σ when that is broader.
  const Eigen::SelfAdjointEigenSolver<Matrix3d> eb(r.cov_gyro_bias);
  const double wb_std = std::max(o.gyro_bias_std, 3.0 * std::sqrt(std::max(0.0, eb.eigenvalues().maxCoeff())));
  s.P = prior_covariance(std::min(v_std, o.velocity_std_motion), o.accel_bias_std, wb_std,
                         std::min(g_std, o.gravity_std_motion), R);
  constrain_gravity_magnitude(s, o);
  return s;
}

}  // namespace rtslam::strategies
