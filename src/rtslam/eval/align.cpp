#include "rtslam/eval/align.hpp"

#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <fmt/format.h>

#include "rtslam/core/error.hpp"

namespace rtslam::eval {

Alignment parse_alignment(std::string_view name) {
  if (name == "se3") return Alignment::Se3;
  if (name == "sim3") return Alignment::Sim3;
  if (name == "posyaw") return Alignment::PosYaw;
  if (name == "origin") return Alignment::Origin;
  if (name == "none") return Alignment::None;
  throw ConfigError(fmt::format("alignment '{}' is unknown (expected se3, sim3, posyaw, origin or none)", name));
}

std::string to_string(Alignment a) {
  switch (a) {
    case Alignment::Se3: return "se3";
    case Alignment::Sim3: return "sim3";
    case Alignment::PosYaw: return "posyaw";
    case Alignment::Origin: return "origin";
    case Alignment::None: return "none";
  }
  return "?";
}

Sim3 umeyama(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst, bool with_scale) {
  if (src.size() != dst.size())
    throw DataError(fmt::format("umeyama: {} source points but {} target points", src.size(), dst.size()));
  if (src.size() < 3) throw DataError(fmt::format("umeyama: need at least 3 point pairs, got {}", src.size()));
  const double n = static_cast<double>(src.size());
  Eigen::Vector3d mean_x = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_y = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < src.size(); ++i) {
    mean_x += src[i];
    mean_y += dst[i];
  }
  mean_x /= n;
  mean_y /= n;
  // Umeyama eqs. 36 and 38: variance of the source and cross-covariance Σ_xy = 1/n Σ (y − ȳ)(x − x̄)ᵀ.
  double sigma_x = 0.0;
  Eigen::Matrix3d cov_xy = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < src.size(); ++i) {
    const Eigen::Vector3d dx = src[i] - mean_x;
    sigma_x += dx.squaredNorm();
    cov_xy += (dst[i] - mean_y) * dx.transpose();
  }
  sigma_x /= n;
  cov_xy /= n;
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov_xy, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d d = svd.singularValues();
  const double eps = std::numeric_limits<double>::epsilon();
  const int rank = (d.array() > eps).count();
  if (rank < 2) throw DataError("umeyama: degenerate point sets (covariance rank < 2), alignment is not possible");
  // Eq. 43: S = diag(1, 1, −1) when det(U)·det(V) < 0 (a reflection otherwise).
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) S(2, 2) = -1.0;
  Sim3 out;
  out.R = svd.matrixU() * S * svd.matrixV().transpose();  // eq. 40
  out.s = with_scale ? (d.asDiagonal() * S).trace() / sigma_x : 1.0;  // eq. 42
  out.t = mean_y - out.s * (out.R * mean_x);  // eq. 41
  return out;
}

Sim3 align_position_yaw(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst) {
  if (src.size() != dst.size())
    throw DataError(fmt::format("position+yaw alignment: {} source points but {} target points", src.size(),
                                dst.size()));
  if (src.empty()) throw DataError("position+yaw alignment: no point pairs");
  const double n = static_cast<double>(src.size());
  Eigen::Vector3d mean_x = Eigen::Vector3d::Zero();
  Eigen::Vector3d mean_y = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < src.size(); ++i) {
    mean_x += src[i];
    mean_y += dst[i];
  }
  mean_x /= n;
  mean_y /= n;
  // Minimizing Σ |y' − R_z(ψ) x'|² over ψ maximizes Σ y'ᵀ R_z(ψ) x' = A cos ψ + B sin ψ, with
  // A = Σ (x'_x y'_x + x'_y y'_y), B = Σ (x'_x y'_y − x'_y y'_x): ψ = atan2(B, A).
  double A = 0.0;
  double B = 0.0;
  for (std::size_t i = 0; i < src.size(); ++i) {
    const Eigen::Vector3d x = src[i] - mean_x;
    const Eigen::Vector3d y = dst[i] - mean_y;
    A += x.x() * y.x() + x.y() * y.y();
    B += x.x() * y.y() - x.y() * y.x();
  }
  Sim3 out;
  if (std::hypot(A, B) > 0.0) {
    out.R = rot_z(std::atan2(B, A));
  } else if (src.size() > 1) {
    throw DataError("position+yaw alignment: degenerate point sets (no horizontal spread), yaw is unobservable");
  }
  out.t = mean_y - out.R * mean_x;
  return out;
}

namespace {
std::vector<Eigen::Vector3d> positions(const Trajectory& traj) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(traj.poses.size());
  for (const auto& p : traj.poses) out.push_back(p.p_WR);
  return out;
}
}  // namespace

void check_alignment_geometry(const std::vector<Eigen::Vector3d>& est, const std::vector<Eigen::Vector3d>& gt,
                              Alignment method) {
  if (method != Alignment::Se3 && method != Alignment::Sim3) return;
  // A fit needs more numbers than it has parameters, or its residual (the ATE) is the leftover of an interpolation:
  // 3n coordinates, 6 (SE3) or 7 (Sim3) parameters; at least as many residual degrees of freedom as parameters.
  const std::size_t params = method == Alignment::Sim3 ? 7 : 6;
  const std::size_t min_poses = (2 * params + 2) / 3;  // 3n - p >= p
  if (est.size() < min_poses) {
    throw DataError(fmt::format("{} alignment: {} associated poses, at least {} needed (it fits {} parameters to 3 "
                                "coordinates a pose; fewer poses make the ATE the residual of an interpolation)",
                                to_string(method), est.size(), min_poses, params));
  }
  // Collinear positions leave the rotation about their line undetermined (and a Sim3 scale ill-conditioned).
  for (const auto* set : {&gt, &est}) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : *set) mean += p;
    mean /= static_cast<double>(set->size());
    Eigen::Matrix3d C = Eigen::Matrix3d::Zero();
    for (const auto& p : *set) C += (p - mean) * (p - mean).transpose();
    const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(C / static_cast<double>(set->size()),
                                                                              Eigen::EigenvaluesOnly)
                                   .eigenvalues()
                                   .cwiseMax(0.0)
                                   .cwiseSqrt();  // principal standard deviations, ascending
    if (!(ev[1] > kMinAlignmentSpreadRatio * ev[2])) {
      throw DataError(fmt::format(
          "{} alignment: the {} positions lie on a line (spread {:.3g} m along it, {:.3g} m across): the rotation "
          "about it is undetermined; use the origin or none alignment (`--align origin`, Python align=\"origin\"), "
          "or a longer trajectory",
          to_string(method), set == &gt ? "ground-truth" : "estimated", ev[2], ev[1]));
    }
  }
}

Sim3 compute_alignment(const Trajectory& est, const Trajectory& gt, Alignment method) {
  if (est.poses.size() != gt.poses.size())
    throw DataError(fmt::format("alignment: trajectories are not associated ({} vs {} poses)", est.poses.size(),
                                gt.poses.size()));
  if (est.poses.empty()) throw DataError("alignment: no associated poses");
  check_alignment_geometry(positions(est), positions(gt), method);
  switch (method) {
    case Alignment::Se3: return umeyama(positions(est), positions(gt), false);
    case Alignment::Sim3: return umeyama(positions(est), positions(gt), true);
    case Alignment::PosYaw: return align_position_yaw(positions(est), positions(gt));
    case Alignment::Origin: {
      // S = T_gt0 · T_est0⁻¹, so that the first estimated pose lands exactly on the first true pose.
      const auto& e = est.poses.front();
      const auto& g = gt.poses.front();
      Sim3 S;
      // Normalized: files hold quaternions rounded to a few decimals (the readers accept norms within 1 %).
      S.R = g.q_WR.normalized().toRotationMatrix() * e.q_WR.normalized().toRotationMatrix().transpose();
      S.t = g.p_WR - S.R * e.p_WR;
      return S;
    }
    case Alignment::None: return Sim3{};
  }
  return Sim3{};
}

AlignmentSpread alignment_spread(const Trajectory& aligned, const Trajectory& gt, Alignment method) {
  if (method != Alignment::Se3 && method != Alignment::Sim3) {
    throw DataError(fmt::format("alignment spread: {} is not a least-squares fit", to_string(method)));
  }
  if (aligned.poses.size() != gt.poses.size()) {
    throw DataError(fmt::format("alignment spread: trajectories are not associated ({} vs {} poses)",
                                aligned.poses.size(), gt.poses.size()));
  }
  const std::size_t n = aligned.poses.size();
  const std::size_t params = method == Alignment::Sim3 ? 7 : 6;
  if (3 * n <= params) throw DataError(fmt::format("alignment spread: {} poses fit no {} parameters", n, params));
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  double sse = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    mean += aligned.poses[i].p_WR;
    sse += (gt.poses[i].p_WR - aligned.poses[i].p_WR).squaredNorm();
  }
  mean /= static_cast<double>(n);
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  double spread = 0.0;  // Σ|r|²
  for (const auto& pose : aligned.poses) {
    const Eigen::Vector3d r = pose.p_WR - mean;
    J += r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose();
    spread += r.squaredNorm();
  }
  const double sigma = std::sqrt(sse / static_cast<double>(3 * n - params));
  const double lambda_min = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(J, Eigen::EigenvaluesOnly).eigenvalues()[0];
  constexpr double kInf = std::numeric_limits<double>::infinity();
  AlignmentSpread out;
  out.rotation_std_deg = lambda_min > 0.0 ? sigma / std::sqrt(lambda_min) * 180.0 / std::numbers::pi : kInf;
  out.scale_rel_std = spread > 0.0 ? sigma / std::sqrt(spread) : kInf;
  return out;
}

Trajectory apply_alignment(const Sim3& S, const Trajectory& est) {
  Trajectory out = est;
  const Eigen::Quaterniond q_S(S.R);
  for (auto& pose : out.poses) {
    pose.p_WR = S.apply(pose.p_WR);
    pose.q_WR = (q_S * pose.q_WR).normalized();
    if (pose.v_WR) *pose.v_WR = S.s * (S.R * *pose.v_WR);
    if (pose.cov) {
      Eigen::Matrix<double, 6, 6> J = Eigen::Matrix<double, 6, 6>::Identity();
      J.topLeftCorner<3, 3>() = S.s * S.R;
      *pose.cov = J * *pose.cov * J.transpose();
    }
  }
  return out;
}

}  // namespace rtslam::eval
