#include "rtslam/eval/nees.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>

#include <Eigen/Cholesky>
#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/eval/chi2.hpp"
#include "rtslam/eval/geometry.hpp"

namespace rtslam::eval {

NeesSeries compute_nees(const Trajectory& est, const Trajectory& gt) {
  if (est.poses.size() != gt.poses.size())
    throw DataError(fmt::format("NEES: trajectories must be associated ({} vs {} poses)", est.poses.size(),
                                gt.poses.size()));
  if (est.poses.empty()) throw DataError("NEES: no associated poses");
  // S = T_est0 · T_gt0⁻¹ maps the ground truth into the estimate's world frame.
  const Eigen::Quaterniond q_e0 = est.poses.front().q_WR.normalized();
  const Eigen::Quaterniond q_g0 = gt.poses.front().q_WR.normalized();
  const Eigen::Quaterniond q_S = q_e0 * q_g0.conjugate();
  const Eigen::Matrix3d R_S = q_S.toRotationMatrix();
  const Eigen::Vector3d t_S = est.poses.front().p_WR - R_S * gt.poses.front().p_WR;

  NeesSeries out;
  for (std::size_t i = 0; i < est.poses.size(); ++i) {
    const StampedPose& e = est.poses[i];
    if (!e.cov) {
      ++out.skipped;
      continue;
    }
    const Eigen::Matrix<double, 6, 6> P = 0.5 * (*e.cov + e.cov->transpose());
    const Eigen::LLT<Eigen::Matrix<double, 6, 6>> llt(P);
    if (llt.info() != Eigen::Success || !(P.diagonal().array() > 0.0).all()) {
      ++out.skipped;
      continue;
    }
    const Eigen::Vector3d p_true = R_S * gt.poses[i].p_WR + t_S;
    const Eigen::Quaterniond q_true = q_S * gt.poses[i].q_WR.normalized();
    Vector6d err;
    err.head<3>() = p_true - e.p_WR;
    err.tail<3>() = so3_log(e.q_WR.normalized().conjugate() * q_true);
    const double eps = err.dot(llt.solve(err));
    if (!std::isfinite(eps)) {
      ++out.skipped;
      continue;
    }
    out.t.push_back(e.t);
    out.nees.push_back(eps);
    out.error.push_back(err);
    out.sigma.push_back(P.diagonal().cwiseSqrt());
  }
  if (out.nees.empty())
    throw DataError(fmt::format("NEES: no pose of {} has a positive-definite 6x6 covariance",
                                est.source.empty() ? "the estimate" : est.source));
  return out;
}

NeesSummary summarize_nees(const NeesSeries& s, double confidence) {
  NeesSummary out;
  std::tie(out.band_lo, out.band_hi) = nees_band(6, 1, confidence);
  out.n = s.nees.size();
  if (s.nees.empty()) return out;
  std::size_t inside = 0;
  for (double v : s.nees) {
    out.mean += v;
    if (v >= out.band_lo && v <= out.band_hi) ++inside;
  }
  out.mean /= static_cast<double>(s.nees.size());
  out.fraction_in_band = static_cast<double>(inside) / static_cast<double>(s.nees.size());
  return out;
}

AverageNees average_nees(const std::vector<NeesSeries>& runs, double confidence) {
  std::map<TimeNs, std::pair<double, int>> acc;
  for (const auto& run : runs) {
    for (std::size_t i = 0; i < run.t.size(); ++i) {
      auto& a = acc[run.t[i]];
      a.first += run.nees[i];
      a.second += 1;
    }
  }
  AverageNees out;
  std::map<int, std::pair<double, double>> bands;  // band per run count, computed once
  for (const auto& [t, a] : acc) {
    const auto [sum, n] = a;
    auto it = bands.find(n);
    if (it == bands.end()) it = bands.emplace(n, nees_band(6, n, confidence)).first;
    out.t.push_back(t);
    out.mean.push_back(sum / n);
    out.n_runs.push_back(n);
    out.lo.push_back(it->second.first);
    out.hi.push_back(it->second.second);
  }
  return out;
}

NeesSummary summarize_average_nees(const AverageNees& avg) {
  NeesSummary out;
  out.n = avg.mean.size();
  if (avg.mean.empty()) return out;
  std::size_t inside = 0;
  for (std::size_t i = 0; i < avg.mean.size(); ++i) {
    out.mean += avg.mean[i];
    if (avg.mean[i] >= avg.lo[i] && avg.mean[i] <= avg.hi[i]) ++inside;
  }
  out.mean /= static_cast<double>(avg.mean.size());
  out.fraction_in_band = static_cast<double>(inside) / static_cast<double>(avg.mean.size());
  out.n_runs = *std::max_element(avg.n_runs.begin(), avg.n_runs.end());
  out.band_lo = avg.lo[0];
  out.band_hi = avg.hi[0];
  for (std::size_t i = 0; i < avg.n_runs.size(); ++i) {
    if (avg.n_runs[i] == out.n_runs) {
      out.band_lo = avg.lo[i];
      out.band_hi = avg.hi[i];
      break;
    }
  }
  return out;
}

nlohmann::json to_json(const NeesSummary& s) {
  return {{"mean", s.mean}, {"fraction_in_band", s.fraction_in_band}, {"band", {s.band_lo, s.band_hi}},
          {"runs", s.n_runs}, {"poses", s.n}};
}

}  // namespace rtslam::eval
