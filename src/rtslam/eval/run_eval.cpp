#include "rtslam/eval/run_eval.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/io/text.hpp"
#include "rtslam/eval/associate.hpp"
#include "rtslam/io/trajectory_io.hpp"

namespace rtslam::eval {

namespace fs = std::filesystem;

TimingStats compute_timing(const std::vector<double>& ms) {
  TimingStats s;
  s.frames = ms.size();
  if (ms.empty()) return s;
  std::vector<double> sorted = ms;
  std::sort(sorted.begin(), sorted.end());
  double sum = 0.0;
  for (double v : sorted) sum += v;
  s.mean_ms = sum / static_cast<double>(sorted.size());
  const std::size_t n = sorted.size();
  s.median_ms = n % 2 ? sorted[n / 2] : 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]);
  // Nearest-rank 95th percentile.
  const auto rank = static_cast<std::size_t>(std::ceil(0.95 * static_cast<double>(n)));
  s.p95_ms = sorted[std::clamp<std::size_t>(rank, 1, n) - 1];
  s.max_ms = sorted.back();
  return s;
}

const std::vector<double>* CsvTable::column(const std::string& name) const {
  for (std::size_t i = 0; i < names.size(); ++i)
    if (names[i] == name) return &columns[i];
  return nullptr;
}

CsvTable read_csv_table(const std::string& path) {
  io::LineReader reader(path);
  CsvTable table;
  std::string line;
  bool have_header = false;
  while (reader.next(line)) {
    std::string_view v = io::trim(line);
    if (v.empty()) continue;
    if (!have_header) {
      if (v.front() == '#') v.remove_prefix(1);
      for (auto name : io::split(v, ',')) table.names.emplace_back(io::trim(name));
      table.columns.resize(table.names.size());
      have_header = true;
      continue;
    }
    if (v.front() == '#') continue;
    const auto fields = io::split(v, ',');
    if (fields.size() != table.names.size())
      throw IoError(fmt::format("{}:{}: {} fields but the header has {}", path, reader.line_number(), fields.size(),
                                table.names.size()));
    for (std::size_t i = 0; i < fields.size(); ++i) {
      double x = 0.0;
      if (!io::parse_double(fields[i], x))
        throw IoError(fmt::format("{}:{}: field '{}' ({}) is not a number", path, reader.line_number(), fields[i],
                                  table.names[i]));
      table.columns[i].push_back(x);
    }
  }
  if (!have_header) throw IoError(fmt::format("{}: empty CSV (no header line)", path));
  return table;
}

std::vector<double> frame_times_ms(const CsvTable& frames) {
  for (const char* name : {"time_total_ms", "t_total [ms]"})
    if (const auto* ms = frames.column(name)) return *ms;
  return {};
}

std::string find_estimate_file(const std::string& run_dir) {
  for (const char* name : {"trajectory.csv", "trajectory.txt"}) {
    const fs::path p = fs::path(run_dir) / name;
    if (fs::exists(p)) return p.string();
  }
  throw IoError(fmt::format("{}: no estimate (trajectory.csv or trajectory.txt)", run_dir));
}

std::string find_groundtruth_file(const std::string& run_dir) {
  for (const char* name : {"groundtruth.txt", "groundtruth.csv"}) {
    const fs::path p = fs::path(run_dir) / name;
    if (fs::exists(p)) return p.string();
  }
  throw IoError(fmt::format("{}: no ground truth (groundtruth.txt or groundtruth.csv)", run_dir));
}

RunEvaluation evaluate_run(const std::string& run_dir, const EvalOptions& options) {
  if (!fs::is_directory(run_dir)) throw IoError(fmt::format("{}: not a run directory", run_dir));
  RunEvaluation r;
  r.dir = run_dir;
  r.options = options;
  r.estimate_file = find_estimate_file(run_dir);
  r.groundtruth_file = find_groundtruth_file(run_dir);
  const Trajectory est = io::read_trajectory(r.estimate_file);
  const Trajectory gt = io::read_trajectory(r.groundtruth_file);
  r.metrics = evaluate(est, gt, options);
  auto [est_sync, gt_sync] = associate(est, gt, options.association);
  r.est_aligned = apply_alignment(r.metrics.alignment, est_sync);
  r.gt = gt_sync;
  const bool has_cov = std::any_of(est_sync.poses.begin(), est_sync.poses.end(),
                                   [](const StampedPose& p) { return p.cov.has_value(); });
  if (has_cov) {
    try {
      r.nees = compute_nees(est_sync, gt_sync);
      r.nees_summary = summarize_nees(*r.nees);
    } catch (const DataError& e) {
      r.nees_note = e.what();
    }
  } else {
    r.nees_note = fmt::format("{} has no pose covariance", r.estimate_file);
  }
  const fs::path frames = fs::path(run_dir) / "frames.csv";
  if (fs::exists(frames)) {
    const CsvTable table = read_csv_table(frames.string());
    r.frame_time_ms = frame_times_ms(table);
    if (const auto* t = table.column("t_s")) {
      r.frame_t_s = *t;
    } else if (const auto* t_ns = table.column("timestamp [ns]")) {
      for (double v : *t_ns) r.frame_t_s.push_back(v * 1e-9);
    }
  }
  r.timing = compute_timing(r.frame_time_ms);
  return r;
}

nlohmann::json to_json(const RunEvaluation& r, bool with_series) {
  nlohmann::json j = to_json(r.metrics, r.options, with_series);
  j["run_dir"] = r.dir;
  j["estimate"] = r.estimate_file;
  j["ground_truth"] = r.groundtruth_file;
  if (r.nees_summary) {
    j["nees"] = to_json(*r.nees_summary);
    if (with_series) {
      std::vector<double> t;
      for (TimeNs ti : r.nees->t) t.push_back(to_seconds(ti));
      j["nees"]["t_ns"] = r.nees->t;
      j["nees"]["t_s"] = t;
      j["nees"]["values"] = r.nees->nees;
    }
  } else {
    j["nees"] = {{"note", r.nees_note}};
  }
  j["timing"] = {{"frames", r.timing.frames},
                 {"mean_ms", r.timing.mean_ms},
                 {"median_ms", r.timing.median_ms},
                 {"p95_ms", r.timing.p95_ms},
                 {"max_ms", r.timing.max_ms}};
  return j;
}

std::string write_run_eval(const RunEvaluation& r) {
  const std::string path = (fs::path(r.dir) / "eval.json").string();
  std::ofstream out = io::open_for_writing(path);
  out << to_json(r, true).dump(1) << '\n';
  io::close_checked(out, path);
  return path;
}

RunAccuracy evaluate_accuracy(const Trajectory& est, const Trajectory& gt, bool metric_scale) {
  RunAccuracy r;
  r.metric_scale = metric_scale;
  r.options.align = metric_scale ? Alignment::Se3 : Alignment::Sim3;
  r.options.association.interpolate = gt.has_timestamps && est.has_timestamps;
  r.options.with_rpe = false;
  r.ate = evaluate(est, gt, r.options);
  r.scale_error = std::abs(r.ate.sim3_scale - 1.0);
  r.json = to_json(r.ate, r.options);
  r.json["scale_error"] = r.scale_error;
  const double path = r.ate.path_length_m;
  const double pct = path > 0.0 ? 100.0 * r.ate.ate.trans_m.rmse / path : 0.0;
  r.json["ate_percent_of_path"] = pct;
  if (metric_scale && path >= 20.0) {
    EvalOptions ro = r.options;
    ro.with_rpe = true;
    ro.rpe.delta = 10.0;
    ro.rpe.unit = DeltaUnit::Meters;
    ro.rpe.all_pairs = true;
    const EvalResult with_rpe = evaluate(est, gt, ro);
    if (with_rpe.rpe) {
      r.rpe_10m = with_rpe.rpe;
      r.json["rpe_10m"] = {{"trans_m", to_json(with_rpe.rpe->trans_m)}, {"rot_deg", to_json(with_rpe.rpe->rot_deg)},
                           {"pairs", with_rpe.rpe->pairs.size()}};
    }
  }
  const auto [e, g] = associate(est, gt, r.options.association);
  if (std::any_of(e.poses.begin(), e.poses.end(), [](const StampedPose& p) { return p.cov.has_value(); })) {
    try {
      r.nees = summarize_nees(compute_nees(e, g));
      r.json["nees"] = to_json(*r.nees);
    } catch (const Error&) {
      // No positive-definite covariance: no NEES.
    }
  }
  if (metric_scale) {
    r.line = fmt::format("  ATE (SE(3) aligned): RMSE {:.4f} m over the {:.2f} m path (max {:.4f} m); scale error {:.2f} % "
                         "(Sim(3) scale {:.4f})", r.ate.ate.trans_m.rmse, path, r.ate.ate.trans_m.max,
                         100.0 * r.scale_error, r.ate.sim3_scale);
    if (r.rpe_10m) r.line += fmt::format("; RPE per 10 m: {:.4f} m", r.rpe_10m->trans_m.rmse);
  } else {
    r.line = fmt::format("  ATE (Sim(3) aligned): RMSE {:.4f} m = {:.3f} % of the {:.2f} m path; scale {:.4f}",
                         r.ate.ate.trans_m.rmse, pct, path, r.ate.sim3_scale);
  }
  if (const std::string w = alignment_warning(r.ate); !w.empty()) r.line += "\n  " + w;
  if (r.nees) {
    r.line += fmt::format("\n  pose NEES: mean {:.2f}, {:.1f} % inside the 99 % band [{:.2f}, {:.2f}]", r.nees->mean,
                          100.0 * r.nees->fraction_in_band, r.nees->band_lo, r.nees->band_hi);
  }
  r.line += "\n";
  return r;
}

}  // namespace rtslam::eval
