#include "rtslam/eval/associate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <vector>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"

namespace rtslam::eval {
namespace {

std::string name_of(const Trajectory& t, const char* fallback) { return t.source.empty() ? fallback : t.source; }

}  // namespace

std::pair<Trajectory, Trajectory> associate(const Trajectory& est, const Trajectory& gt,
                                            const AssociationOptions& options) {
  if (!(options.max_diff_s >= 0.0))
    throw ConfigError(fmt::format("association: max time difference must be >= 0 s, got {}", options.max_diff_s));
  // An empty file (a run that wrote no pose, a truncated export) says so, not "no matching timestamps".
  for (const auto& [t, what] : {std::pair{&est, "estimate"}, std::pair{&gt, "ground truth"}}) {
    if (t->poses.empty()) {
      throw DataError(fmt::format("association: {} holds no pose (an empty trajectory)", name_of(*t, what)));
    }
  }
  Trajectory est_out;
  Trajectory gt_out;
  est_out.source = est.source;
  gt_out.source = gt.source;
  est_out.has_timestamps = gt_out.has_timestamps = est.has_timestamps && gt.has_timestamps;
  if (!est.has_timestamps || !gt.has_timestamps) {
    if (est.poses.size() != gt.poses.size())
      throw DataError(fmt::format("association by index (no timestamps): {} has {} poses but {} has {}",
                                  name_of(est, "estimate"), est.poses.size(), name_of(gt, "ground truth"),
                                  gt.poses.size()));
    est_out.poses = est.poses;
    gt_out.poses = gt.poses;
    return {est_out, gt_out};
  }
  const TimeNs offset = from_seconds(options.offset_s);
  const TimeNs max_diff = from_seconds(options.max_diff_s);
  if (options.interpolate) {
    if (!(options.max_gap_s > 0.0))
      throw ConfigError(fmt::format("association: interpolation gap must be > 0 s, got {}", options.max_gap_s));
    const TimeNs max_gap = from_seconds(options.max_gap_s);
    const auto& G = gt.poses;
    for (std::size_t j = 1; j < G.size(); ++j)
      if (G[j].t <= G[j - 1].t)
        throw DataError(fmt::format("association: {} is not sorted by time at pose {} (needed to interpolate)",
                                    name_of(gt, "ground truth"), j));
    for (const StampedPose& e : est.poses) {
      const TimeNs t = e.t + offset;
      const auto it = std::lower_bound(G.begin(), G.end(), t, [](const StampedPose& p, TimeNs v) { return p.t < v; });
      if (it == G.end()) continue;
      StampedPose g;
      if (it->t == t) {
        g = *it;
      } else {
        if (it == G.begin()) continue;
        const StampedPose& a = *(it - 1);
        const StampedPose& b = *it;
        if (b.t - a.t > max_gap) continue;
        const double s = static_cast<double>(t - a.t) / static_cast<double>(b.t - a.t);
        g = a;
        g.p_WR = a.p_WR + s * (b.p_WR - a.p_WR);
        g.q_WR = a.q_WR.normalized().slerp(s, b.q_WR.normalized());
        if (a.v_WR && b.v_WR) g.v_WR = *a.v_WR + s * (*b.v_WR - *a.v_WR);
        g.cov.reset();
      }
      g.t = e.t;
      est_out.poses.push_back(e);
      gt_out.poses.push_back(g);
    }
    if (est_out.poses.empty())
      throw DataError(fmt::format("association: no estimate of {} lies inside the time span of {} (interpolation, "
                                  "offset {} s)", name_of(est, "estimate"), name_of(gt, "ground truth"),
                                  options.offset_s));
    return {est_out, gt_out};
  }
  // evo: traj_1 = reference, traj_2 = estimate (offset applies to it); the shorter one drives the matching.
  const bool est_longer = est.poses.size() > gt.poses.size();
  const auto& shorter = est_longer ? gt.poses : est.poses;
  const auto& longer = est_longer ? est.poses : gt.poses;
  // Shift applied to the longer list's stamps relative to the shorter's (evo: +offset if the estimate is longer).
  const TimeNs shift_long = est_longer ? offset : 0;
  const TimeNs shift_short = est_longer ? 0 : offset;
  std::vector<std::size_t> idx_short;
  std::vector<std::size_t> idx_long;
  // Nearest neighbour with the first minimum on ties (numpy argmin), by binary search when the longer list is
  // sorted (the usual case) and by a plain scan otherwise.
  bool sorted = true;
  for (std::size_t j = 1; j < longer.size() && sorted; ++j) sorted = longer[j - 1].t <= longer[j].t;
  for (std::size_t i = 0; i < shorter.size(); ++i) {
    const TimeNs ts = shorter[i].t + shift_short - shift_long;
    std::size_t best = 0;
    TimeNs best_diff = -1;
    if (sorted) {
      const auto it = std::lower_bound(longer.begin(), longer.end(), ts,
                                       [](const StampedPose& p, TimeNs v) { return p.t < v; });
      const auto j = static_cast<std::size_t>(it - longer.begin());
      // Candidates: the first stamp >= ts and the first occurrence of the stamp just before it.
      if (j < longer.size()) {
        best = j;
        best_diff = longer[j].t - ts;
      }
      if (j > 0) {
        std::size_t k = j - 1;
        while (k > 0 && longer[k - 1].t == longer[k].t) --k;
        const TimeNs d = ts - longer[k].t;
        if (best_diff < 0 || d <= best_diff) {
          best = k;
          best_diff = d;
        }
      }
    } else {
      for (std::size_t j = 0; j < longer.size(); ++j) {
        const TimeNs d = std::llabs(longer[j].t - ts);
        if (best_diff < 0 || d < best_diff) {
          best_diff = d;
          best = j;
        }
      }
    }
    if (best_diff >= 0 && best_diff <= max_diff) {
      idx_short.push_back(i);
      idx_long.push_back(best);
    }
  }
  if (idx_short.empty())
    throw DataError(fmt::format("association: no matching timestamps between {} and {} (max diff {} s, offset {} s)",
                                name_of(est, "estimate"), name_of(gt, "ground truth"), options.max_diff_s,
                                options.offset_s));
  for (std::size_t k = 0; k < idx_short.size(); ++k) {
    const auto& s = shorter[idx_short[k]];
    const auto& l = longer[idx_long[k]];
    est_out.poses.push_back(est_longer ? l : s);
    gt_out.poses.push_back(est_longer ? s : l);
  }
  return {est_out, gt_out};
}

}  // namespace rtslam::eval
