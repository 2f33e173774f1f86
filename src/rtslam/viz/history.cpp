#include "rtslam/viz/history.hpp"

#include <algorithm>
#include <cstdlib>

#include <Eigen/Cholesky>

#include "rtslam/eval/geometry.hpp"

namespace rtslam::viz {

HistoryEntry summarize(const FrameReport& r) {
  HistoryEntry h;
  h.index = r.index;
  h.t = r.t;
  h.T_WR = r.T_WR;
  h.cov = r.cov_pose;
  h.stats = r.stats;
  h.has_stats = true;
  h.has_timing = r.has_timing;
  h.nis = frame_nis(r.matches);
  return h;
}

NeesTracker::NeesTracker(Trajectory ground_truth, double max_dt_s)
    : gt_(std::move(ground_truth)), max_dt_ns_(from_seconds(max_dt_s)) {
  std::sort(gt_.poses.begin(), gt_.poses.end(), [](const StampedPose& a, const StampedPose& b) { return a.t < b.t; });
}

const StampedPose* NeesTracker::nearest(TimeNs t) const {
  const auto& g = gt_.poses;
  if (g.empty()) return nullptr;
  auto it = std::lower_bound(g.begin(), g.end(), t, [](const StampedPose& p, TimeNs tt) { return p.t < tt; });
  const StampedPose* best = nullptr;
  if (it != g.end()) best = &*it;
  if (it != g.begin()) {
    const StampedPose* prev = &*std::prev(it);
    if (best == nullptr || std::llabs(prev->t - t) <= std::llabs(best->t - t)) best = prev;
  }
  if (best == nullptr || std::llabs(best->t - t) > max_dt_ns_) return nullptr;
  return best;
}

double NeesTracker::nees(const HistoryEntry& e) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  const StampedPose* g = nearest(e.t);
  if (g == nullptr) return kNaN;
  if (!gauge_set_) {
    // S = T_est0 · T_gt0⁻¹ (eval/nees.hpp), from the first estimate that has a ground truth.
    const Eigen::Quaterniond q_S = e.T_WR.q.normalized() * g->q_WR.normalized().conjugate();
    S_.q = q_S;
    S_.p = e.T_WR.p - q_S * g->p_WR;
    gauge_set_ = true;
  }
  if (!e.cov) return kNaN;
  const Eigen::Matrix<double, 6, 6> P = 0.5 * (*e.cov + e.cov->transpose());
  const Eigen::LLT<Eigen::Matrix<double, 6, 6>> llt(P);
  if (llt.info() != Eigen::Success || !(P.diagonal().array() > 0.0).all()) return kNaN;
  const Eigen::Vector3d p_true = S_.q * g->p_WR + S_.p;
  const Eigen::Quaterniond q_true = S_.q * g->q_WR.normalized();
  Eigen::Matrix<double, 6, 1> err;
  err.head<3>() = p_true - e.T_WR.p;
  err.tail<3>() = eval::so3_log(e.T_WR.q.normalized().conjugate() * q_true);
  const double eps = err.dot(llt.solve(err));
  return std::isfinite(eps) ? eps : kNaN;
}

}  // namespace rtslam::viz
