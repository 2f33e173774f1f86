#include "rtslam/eval/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/eval/geometry.hpp"

namespace rtslam::eval {
namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

struct Pose {
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
};

Pose pose_of(const StampedPose& p) { return {p.q_WR.normalized().toRotationMatrix(), p.p_WR}; }

// a⁻¹ b
Pose relative(const Pose& a, const Pose& b) { return {a.R.transpose() * b.R, a.R.transpose() * (b.t - a.t)}; }

void check_associated(const Trajectory& est, const Trajectory& gt, const char* what) {
  if (est.poses.size() != gt.poses.size())
    throw DataError(fmt::format("{}: trajectories must be associated ({} vs {} poses)", what, est.poses.size(),
                                gt.poses.size()));
  if (est.poses.empty()) throw DataError(fmt::format("{}: no associated poses", what));
}

}  // namespace

ErrorStats compute_stats(const std::vector<double>& errors) {
  if (errors.empty()) throw DataError("error statistics: empty error list");
  ErrorStats s;
  s.n = errors.size();
  const double n = static_cast<double>(s.n);
  double sum = 0.0;
  for (double e : errors) {
    sum += e;
    s.sse += e * e;
  }
  s.mean = sum / n;
  s.rmse = std::sqrt(s.sse / n);
  double var = 0.0;
  for (double e : errors) var += (e - s.mean) * (e - s.mean);
  s.std = std::sqrt(var / n);
  std::vector<double> sorted = errors;
  std::sort(sorted.begin(), sorted.end());
  s.min = sorted.front();
  s.max = sorted.back();
  const std::size_t mid = s.n / 2;
  s.median = s.n % 2 == 1 ? sorted[mid] : 0.5 * (sorted[mid - 1] + sorted[mid]);
  return s;
}

AteResult compute_ate(const Trajectory& est_aligned, const Trajectory& gt) {
  check_associated(est_aligned, gt, "ATE");
  AteResult r;
  for (std::size_t i = 0; i < gt.poses.size(); ++i) {
    const Pose e = pose_of(est_aligned.poses[i]);
    const Pose g = pose_of(gt.poses[i]);
    r.t.push_back(gt.poses[i].t);
    r.trans_err_m.push_back((e.t - g.t).norm());
    r.rot_err_deg.push_back(rotation_angle(e.R.transpose() * g.R) * kRadToDeg);
  }
  r.trans_m = compute_stats(r.trans_err_m);
  r.rot_deg = compute_stats(r.rot_err_deg);
  return r;
}

DeltaUnit parse_delta_unit(const std::string& name) {
  if (name == "frames" || name == "f") return DeltaUnit::Frames;
  if (name == "m" || name == "meters") return DeltaUnit::Meters;
  if (name == "s" || name == "seconds") return DeltaUnit::Seconds;
  throw ConfigError(fmt::format("delta unit '{}' is unknown (expected frames, m or s)", name));
}

std::string to_string(DeltaUnit u) {
  switch (u) {
    case DeltaUnit::Frames: return "frames";
    case DeltaUnit::Meters: return "m";
    case DeltaUnit::Seconds: return "s";
  }
  return "?";
}

std::vector<std::pair<std::size_t, std::size_t>> rpe_pairs(const Trajectory& traj, const RpeOptions& o) {
  using Pairs = std::vector<std::pair<std::size_t, std::size_t>>;
  const auto& poses = traj.poses;
  const std::size_t n = poses.size();
  if (!(o.delta > 0.0)) throw ConfigError(fmt::format("RPE delta must be > 0, got {}", o.delta));
  if (o.unit == DeltaUnit::Seconds && !traj.has_timestamps)
    throw ConfigError("RPE delta in seconds needs timestamps (KITTI files have none): use frames or m");
  Pairs pairs;
  if (o.unit == DeltaUnit::Frames) {
    if (o.delta != std::floor(o.delta))
      throw ConfigError(fmt::format("RPE delta in frames must be an integer, got {}", o.delta));
    const auto d = static_cast<std::size_t>(o.delta);
    if (o.all_pairs) {
      for (std::size_t i = 0; i + d < n; ++i) pairs.emplace_back(i, i + d);
    } else {
      for (std::size_t i = 0; i + d < n; i += d) pairs.emplace_back(i, i + d);
    }
  } else {
    // Accumulated "distance" along the sequence: path length (m) or elapsed time (s).
    std::vector<double> acc(n, 0.0);
    for (std::size_t i = 1; i < n; ++i) {
      acc[i] = acc[i - 1] + (o.unit == DeltaUnit::Meters ? (poses[i].p_WR - poses[i - 1].p_WR).norm()
                                                          : to_seconds(poses[i].t - poses[i - 1].t));
    }
    if (o.all_pairs) {
      // evo: for each i, the j > i whose accumulated distance from i is nearest δ (first on ties), within tol.
      const double tol = o.delta * o.rel_delta_tol;
      for (std::size_t i = 0; i + 1 < n; ++i) {
        std::size_t best = i + 1;
        double best_res = std::abs(acc[i + 1] - acc[i] - o.delta);
        for (std::size_t j = i + 2; j < n; ++j) {
          const double res = std::abs(acc[j] - acc[i] - o.delta);
          if (res < best_res) {
            best_res = res;
            best = j;
          }
        }
        if (best_res <= tol) pairs.emplace_back(i, best);
      }
    } else if (o.unit == DeltaUnit::Meters) {
      // evo's consecutive mode: the path restarts at each id; the first id is where it first reaches δ.
      std::vector<std::size_t> ids;
      double path = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        if (i > 0) path += (poses[i].p_WR - poses[i - 1].p_WR).norm();
        if (path >= o.delta) {
          ids.push_back(i);
          path = 0.0;
        }
      }
      for (std::size_t k = 0; k + 1 < ids.size(); ++k) pairs.emplace_back(ids[k], ids[k + 1]);
    } else {
      std::vector<std::size_t> ids{0};
      for (std::size_t i = 1; i < n; ++i) {
        if (to_seconds(poses[i].t - poses[ids.back()].t) >= o.delta) ids.push_back(i);
      }
      for (std::size_t k = 0; k + 1 < ids.size(); ++k) pairs.emplace_back(ids[k], ids[k + 1]);
    }
  }
  if (pairs.empty())
    throw DataError(fmt::format("RPE: delta = {} {} gives no pose pair in {} poses; try a smaller delta", o.delta,
                                to_string(o.unit), n));
  return pairs;
}

RpeResult compute_rpe(const Trajectory& est_aligned, const Trajectory& gt, const RpeOptions& options) {
  check_associated(est_aligned, gt, "RPE");
  RpeResult r;
  r.pairs = rpe_pairs(options.pairs_from_reference ? gt : est_aligned, options);
  for (const auto& [i, j] : r.pairs) {
    const Pose Q_rel = relative(pose_of(gt.poses[i]), pose_of(gt.poses[j]));
    const Pose P_rel = relative(pose_of(est_aligned.poses[i]), pose_of(est_aligned.poses[j]));
    const Pose E = relative(Q_rel, P_rel);
    r.t.push_back(gt.poses[j].t);
    r.trans_err_m.push_back(E.t.norm());
    r.rot_err_deg.push_back(rotation_angle(E.R) * kRadToDeg);
  }
  r.trans_m = compute_stats(r.trans_err_m);
  r.rot_deg = compute_stats(r.rot_err_deg);
  return r;
}

EvalResult evaluate(const Trajectory& est, const Trajectory& gt, const EvalOptions& options) {
  EvalResult r;
  r.n_est = est.poses.size();
  r.n_gt = gt.poses.size();
  const auto [est_sync, gt_sync] = associate(est, gt, options.association);
  r.n_matched = est_sync.poses.size();
  r.align = options.align;
  r.alignment = compute_alignment(est_sync, gt_sync, options.align);
  if (est_sync.poses.size() >= 3) {
    try {
      const Sim3 S = compute_alignment(est_sync, gt_sync, Alignment::Sim3);
      r.sim3_scale = S.s;
      r.sim3_scale_rel_std = alignment_spread(apply_alignment(S, est_sync), gt_sync, Alignment::Sim3).scale_rel_std;
    } catch (const DataError&) {
      r.sim3_scale = std::nan("");
    }
  } else {
    r.sim3_scale = std::nan("");
  }
  // KITTI poses have no times (their "stamps" are indices): no duration.
  r.duration_s = gt_sync.has_timestamps ? to_seconds(gt_sync.poses.back().t - gt_sync.poses.front().t) : std::nan("");
  for (std::size_t i = 1; i < gt_sync.poses.size(); ++i)
    r.path_length_m += (gt_sync.poses[i].p_WR - gt_sync.poses[i - 1].p_WR).norm();
  const Trajectory est_aligned = apply_alignment(r.alignment, est_sync);
  r.ate = compute_ate(est_aligned, gt_sync);
  if (options.align == Alignment::Se3 || options.align == Alignment::Sim3) {
    r.alignment_rotation_std_deg = alignment_spread(est_aligned, gt_sync, options.align).rotation_std_deg;
  }
  if (options.with_rpe) {
    try {
      r.rpe = compute_rpe(est_aligned, gt_sync, options.rpe);
    } catch (const DataError& e) {
      r.rpe_error = e.what();
    }
  }
  return r;
}

nlohmann::json to_json(const ErrorStats& s) {
  return {{"n", s.n},     {"rmse", s.rmse}, {"mean", s.mean}, {"median", s.median},
          {"std", s.std}, {"min", s.min},   {"max", s.max},   {"sse", s.sse}};
}

namespace {
// JSON has no NaN: write null.
nlohmann::json number_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }
}  // namespace

nlohmann::json to_json(const EvalOptions& o) {
  return {{"align", to_string(o.align)},
          {"association",
           {{"max_diff_s", o.association.max_diff_s},
            {"offset_s", o.association.offset_s},
            {"interpolate", o.association.interpolate},
            {"max_gap_s", o.association.max_gap_s}}},
          {"with_rpe", o.with_rpe},
          {"rpe",
           {{"delta", o.rpe.delta},
            {"unit", to_string(o.rpe.unit)},
            {"all_pairs", o.rpe.all_pairs},
            {"rel_delta_tol", o.rpe.rel_delta_tol},
            {"pairs_from_reference", o.rpe.pairs_from_reference}}}};
}

nlohmann::json to_json(const EvalResult& r, const EvalOptions& o, bool with_series) {
  nlohmann::json j;
  j["options"] = to_json(o);
  j["poses"] = {{"estimate", r.n_est}, {"ground_truth", r.n_gt}, {"matched", r.n_matched}};
  j["association"] = {{"max_diff_s", o.association.max_diff_s}, {"offset_s", o.association.offset_s}};
  if (o.association.interpolate) {  // the ground truth interpolated: max_gap_s bounds it, max_diff_s is not used
    j["association"] = {
        {"interpolate", true}, {"max_gap_s", o.association.max_gap_s}, {"offset_s", o.association.offset_s}};
  }
  j["alignment"] = {{"method", to_string(r.align)},
                    {"scale", r.alignment.s},
                    {"rotation", {r.alignment.R(0, 0), r.alignment.R(0, 1), r.alignment.R(0, 2),
                                  r.alignment.R(1, 0), r.alignment.R(1, 1), r.alignment.R(1, 2),
                                  r.alignment.R(2, 0), r.alignment.R(2, 1), r.alignment.R(2, 2)}},
                    {"translation", {r.alignment.t.x(), r.alignment.t.y(), r.alignment.t.z()}}};
  j["sim3_scale"] = number_or_null(r.sim3_scale);
  j["sim3_scale_rel_std"] = number_or_null(r.sim3_scale_rel_std);
  j["alignment"]["rotation_std_deg"] = number_or_null(r.alignment_rotation_std_deg);
  j["duration_s"] = number_or_null(r.duration_s);
  j["path_length_m"] = r.path_length_m;
  j["ate"] = {{"trans_m", to_json(r.ate.trans_m)}, {"rot_deg", to_json(r.ate.rot_deg)}};
  if (with_series) {
    std::vector<double> t;
    for (TimeNs ti : r.ate.t) t.push_back(to_seconds(ti));
    j["ate"]["t_s"] = t;
    j["ate"]["trans_err_m"] = r.ate.trans_err_m;
    j["ate"]["rot_err_deg"] = r.ate.rot_err_deg;
  }
  if (r.rpe) {
    j["rpe"] = {{"delta", o.rpe.delta},
                {"delta_unit", to_string(o.rpe.unit)},
                {"all_pairs", o.rpe.all_pairs},
                {"pairs", r.rpe->pairs.size()},
                {"trans_m", to_json(r.rpe->trans_m)},
                {"rot_deg", to_json(r.rpe->rot_deg)}};
    if (with_series) {
      j["rpe"]["trans_err_m"] = r.rpe->trans_err_m;
      j["rpe"]["rot_err_deg"] = r.rpe->rot_err_deg;
    }
  } else if (!r.rpe_error.empty()) {
    j["rpe"] = {{"error", r.rpe_error}};
  }
  return j;
}

std::string alignment_warning(const EvalResult& r) {
  // NaN (no such fit) compares false; an infinite spread (no motion at all) true.
  const bool rotation = r.alignment_rotation_std_deg > kMaxAlignmentRotationStdDeg;
  const bool scale = r.sim3_scale_rel_std > kMaxAlignmentScaleStd;
  if (!rotation && !scale) return {};
  std::string what;
  if (rotation) what = fmt::format("its rotation is uncertain by {:.3g} deg", r.alignment_rotation_std_deg);
  if (scale) {
    what += fmt::format("{}the Sim(3) scale {}by {:.3g} %", rotation ? " and " : "", rotation ? "" : "is uncertain ",
                        100.0 * r.sim3_scale_rel_std);
  }
  // Little motion, or residuals large against it (a wrong scale under SE(3)): either leaves the fit loose.
  return fmt::format("warning: the alignment is weakly determined ({:.3f} m of ground-truth path, ATE {:.4f} m): {} "
                     "(first order), so {} say{} little about the run{}",
                     r.path_length_m, r.ate.trans_m.rmse, what,
                     rotation && scale ? "the ATE rotation and the scale"
                     : rotation        ? "the ATE rotation"
                                       : "the scale",
                     rotation && scale ? "" : "s",
                     rotation ? "; `rtslam eval --align origin` compares from the first pose" : "");
}

std::string format_table(const EvalResult& r, const EvalOptions& o) {
  std::string out;
  out += fmt::format("poses: {} estimated, {} ground truth, {} matched; {}{:.2f} m of ground truth\n", r.n_est, r.n_gt,
                     r.n_matched, std::isfinite(r.duration_s) ? fmt::format("{:.2f} s, ", r.duration_s) : "",
                     r.path_length_m);
  out += fmt::format("alignment: {} (scale {:.6f}); Sim(3) scale estimate {:.6f}\n", to_string(r.align),
                     r.alignment.s, r.sim3_scale);
  if (const std::string w = alignment_warning(r); !w.empty()) out += w + "\n";
  out += fmt::format("{:<22} {:>6} {:>11} {:>11} {:>11} {:>11} {:>11} {:>11}\n", "metric", "n", "rmse", "mean",
                     "median", "std", "min", "max");
  auto row = [&out](const std::string& name, const ErrorStats& s) {
    out += fmt::format("{:<22} {:>6} {:>11.6f} {:>11.6f} {:>11.6f} {:>11.6f} {:>11.6f} {:>11.6f}\n", name, s.n,
                       s.rmse, s.mean, s.median, s.std, s.min, s.max);
  };
  row("ATE trans (m)", r.ate.trans_m);
  row("ATE rot (deg)", r.ate.rot_deg);
  if (r.rpe) {
    const std::string d = fmt::format("{:g}{}", o.rpe.delta, to_string(o.rpe.unit) == "frames" ? "f" : to_string(o.rpe.unit));
    row("RPE trans (m) /" + d, r.rpe->trans_m);
    row("RPE rot (deg) /" + d, r.rpe->rot_deg);
  } else if (!r.rpe_error.empty()) {
    out += "RPE: " + r.rpe_error + "\n";
  }
  return out;
}

}  // namespace rtslam::eval
