// rtslam eval EST GT: ATE/RPE (evo-compatible) and, when the estimate carries covariances, NEES; prints a table
// and writes JSON.
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>

#include <fmt/format.h>

#include "commands.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/eval/metrics.hpp"
#include "rtslam/eval/nees.hpp"
#include "rtslam/io/trajectory_io.hpp"

namespace rtslam::cli {

namespace {

struct EvalArgs {
  std::string est, gt, json_out, est_format = "auto", gt_format = "auto";
  std::string align = "se3", delta_unit = "frames";
  double delta = 1.0, t_max_diff = 0.01, t_offset = 0.0, max_gap = 0.1;
  bool interpolate = false;
  bool all_pairs = false, pairs_from_reference = false, series = false;
};

io::TrajectoryFormat parse_format(const std::string& s) {
  if (s == "auto") return io::TrajectoryFormat::Auto;
  if (s == "tum") return io::TrajectoryFormat::Tum;
  if (s == "euroc") return io::TrajectoryFormat::EurocCsv;
  if (s == "kitti") return io::TrajectoryFormat::Kitti;
  throw ConfigError(fmt::format("trajectory format '{}' is unknown (expected auto, tum, euroc or kitti)", s));
}

void run_eval(const EvalArgs& a) {
  eval::EvalOptions o;
  o.align = eval::parse_alignment(a.align);
  o.association.max_diff_s = a.t_max_diff;
  o.association.offset_s = a.t_offset;
  o.association.interpolate = a.interpolate;
  o.association.max_gap_s = a.max_gap;
  o.rpe.delta = a.delta;
  o.rpe.unit = eval::parse_delta_unit(a.delta_unit);
  o.rpe.all_pairs = a.all_pairs;
  o.rpe.pairs_from_reference = a.pairs_from_reference;
  const Trajectory est = io::read_trajectory(a.est, parse_format(a.est_format));
  const Trajectory gt = io::read_trajectory(a.gt, parse_format(a.gt_format));
  const eval::EvalResult r = eval::evaluate(est, gt, o);
  nlohmann::json j = eval::to_json(r, o, a.series);
  j["estimate"] = a.est;
  j["ground_truth"] = a.gt;
  std::cout << eval::format_table(r, o);
  const auto [est_sync, gt_sync] = eval::associate(est, gt, o.association);
  const bool has_cov = std::any_of(est_sync.poses.begin(), est_sync.poses.end(),
                                   [](const StampedPose& p) { return p.cov.has_value(); });
  if (has_cov) {
    // Covariances that give no NEES (none positive definite) leave it out, as `rtslam report` does: the accuracy above
    // stands, and the JSON is still written.
    try {
      const eval::NeesSeries s = eval::compute_nees(est_sync, gt_sync);
      const eval::NeesSummary ns = eval::summarize_nees(s);
      std::cout << fmt::format("NEES (6-DoF pose, first-pose aligned): mean {:.3f} over {} poses, {:.1f} % inside "
                               "the 99 % band [{:.3f}, {:.2f}]\n",
                               ns.mean, ns.n, 100.0 * ns.fraction_in_band, ns.band_lo, ns.band_hi);
      j["nees"] = eval::to_json(ns);
      if (a.series) j["nees"]["values"] = s.nees;
    } catch (const DataError& e) {
      std::cout << "NEES: none (" << e.what() << ")\n";
      j["nees"] = {{"note", e.what()}};
    }
  }
  std::string out = a.json_out;
  if (out.empty()) {
    std::filesystem::path p(a.est);
    out = (p.parent_path() / (p.stem().string() + ".eval.json")).string();
  }
  std::ofstream f(out);
  if (!f) throw IoError(fmt::format("{}: cannot write", out));
  f << j.dump(1) << '\n';
  if (!f) throw IoError(fmt::format("{}: write failed", out));
  std::cout << "wrote " << out << '\n';
}

}  // namespace

void register_eval(CLI::App& app) {
  auto a = std::make_shared<EvalArgs>();
  auto* sub = app.add_subcommand(
      "eval", "Evaluate an estimated trajectory against ground truth: ATE, RPE (evo definitions), NEES");
  sub->add_option("EST", a->est, "estimated trajectory (TUM text, EuRoC/rtslam CSV or KITTI poses)")->required();
  sub->add_option("GT", a->gt, "ground-truth trajectory (same formats)")->required();
  sub->add_option("--align", a->align, "se3, sim3, posyaw (4-DoF), origin (first pose) or none")->capture_default_str();
  sub->add_option("--delta", a->delta, "RPE delta")->capture_default_str();
  sub->add_option("--delta-unit", a->delta_unit, "RPE delta unit: frames, m or s")->capture_default_str();
  sub->add_flag("--all-pairs", a->all_pairs, "RPE over all pairs instead of consecutive ones");
  sub->add_flag("--pairs-from-reference", a->pairs_from_reference, "choose RPE pairs on the ground truth");
  sub->add_option("--t-max-diff", a->t_max_diff, "association tolerance (s)")->capture_default_str();
  sub->add_flag("--interpolate", a->interpolate,
                "evaluate the ground truth at the estimate's timestamps (linear position, slerp attitude) instead of "
                "nearest-neighbour association: for ground truth sampled at other instants than the images");
  sub->add_option("--max-gap", a->max_gap, "--interpolate: largest gap between ground-truth poses to interpolate (s)")
      ->capture_default_str();
  sub->add_option("--t-offset", a->t_offset, "time offset added to the estimate (s)")->capture_default_str();
  sub->add_option("--est-format", a->est_format, "auto, tum, euroc or kitti")->capture_default_str();
  sub->add_option("--gt-format", a->gt_format, "auto, tum, euroc or kitti")->capture_default_str();
  sub->add_option("--json", a->json_out, "JSON output (default: EST's folder, <stem>.eval.json)");
  sub->add_flag("--series", a->series, "include per-pose error arrays in the JSON");
  sub->callback([a] { run_eval(*a); });
}

}  // namespace rtslam::cli
