#include "rtslam/eval/batch.hpp"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <set>
#include <thread>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/io/text.hpp"
#include "rtslam/eval/process.hpp"

namespace rtslam::eval {

namespace fs = std::filesystem;

namespace {

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out = io::open_for_writing(path);
  out << text;
  io::close_checked(out, path);
}

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw IoError(fmt::format("{}: cannot open", path));
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw IoError(fmt::format("{}: invalid JSON ({})", path, e.what()));
  }
}

std::string absolute(const std::string& p) { return fs::absolute(fs::path(p)).lexically_normal().string(); }

}  // namespace

std::string label_of(const std::string& spec) {
  if (spec == "sim" || spec == "default") return spec;
  std::string stem = fs::path(spec).stem().string();
  if (stem.empty()) stem = spec;
  for (char& c : stem)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '_';
  return stem;
}

std::vector<RunSpec> plan_batch(const BatchOptions& o) {
  if (o.out_dir.empty()) throw ConfigError("batch: the output directory is empty");
  if (o.datasets.empty()) throw ConfigError("batch: no dataset given");
  if (o.configs.empty()) throw ConfigError("batch: no config given");
  if (o.seeds.empty()) throw ConfigError("batch: no seed given");
  if (o.jobs < 1) throw ConfigError(fmt::format("batch: jobs must be >= 1, got {}", o.jobs));
  if (o.executable.empty()) throw ConfigError("batch: the rtslam executable is unknown");
  std::set<std::int64_t> seeds(o.seeds.begin(), o.seeds.end());
  if (seeds.size() != o.seeds.size()) throw ConfigError("batch: duplicate seeds");
  for (const auto* axis : {&o.datasets, &o.configs}) {
    std::set<std::string> labels;
    for (const auto& s : *axis)
      if (!labels.insert(label_of(s)).second)
        throw ConfigError(fmt::format("batch: '{}' has the same folder label '{}' as another entry", s, label_of(s)));
  }
  const std::string root = absolute(o.out_dir);
  std::vector<RunSpec> runs;
  for (const auto& d : o.datasets) {
    for (const auto& c : o.configs) {
      for (const auto seed : o.seeds) {
        RunSpec r;
        r.dataset = d;
        r.config = c;
        r.seed = seed;
        r.dir = (fs::path(root) / "runs" / label_of(d) / label_of(c) / fmt::format("seed_{:04d}", seed)).string();
        r.argv = {o.executable, "run", "--seed", std::to_string(seed), "--out", r.dir};
        if (o.duration_s > 0.0) {
          r.argv.push_back("--duration");
          r.argv.push_back(io::format_double(o.duration_s));
        }
        if (c != "default") {
          r.argv.push_back("--config");
          r.argv.push_back(absolute(c));
        }
        if (d != "sim") {
          r.argv.push_back("--dataset");
          r.argv.push_back(fs::exists(d) ? absolute(d) : d);
        }
        // The run folder is the batch's: a retried run replaces what an interrupted or failed attempt left there.
        r.argv.push_back("--force");
        r.argv.insert(r.argv.end(), o.extra_args.begin(), o.extra_args.end());
        runs.push_back(std::move(r));
      }
    }
  }
  return runs;
}

// Finished: summary.json exists and does not say "interrupted" or "failed" (docs/outputs.md "Crash safety"), nor
// that the run ended broken (health final lost or diverged, or never tracked: `rtslam run` exited 1 after writing
// every output); the others are retried like runs without one, and counted failed, not aggregated.
bool run_finished(const RunSpec& run) {
  const fs::path summary = fs::path(run.dir) / "summary.json";
  if (!fs::exists(summary)) return false;
  std::ifstream in(summary);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return false;
  const std::string status = j.value("status", "");
  if (status == "interrupted" || status == "failed") return false;
  if (const auto h = j.find("health"); h != j.end() && h->is_object()) {
    if (h->value("final", "ok") != "ok" || h->value("never_tracked", false)) return false;
  }
  return true;
}

std::string format_progress(const BatchProgress& p, int width) {
  const std::size_t finished = p.done + p.skipped + p.failed;
  const double frac = p.total ? static_cast<double>(finished) / static_cast<double>(p.total) : 1.0;
  const int fill = static_cast<int>(std::lround(frac * width));
  std::string bar(1, '[');
  bar.append(static_cast<std::size_t>(fill), '#').append(static_cast<std::size_t>(width - fill), '.').push_back(']');
  std::string eta = "?";
  if (p.done > 0) {
    const double per_run = p.elapsed_s / static_cast<double>(p.done);
    const std::size_t left = p.total - finished;
    eta = fmt::format("{:.0f} s", per_run * static_cast<double>(left));
  }
  return fmt::format("{} {:>4}/{} done ({} resumed), {} failed, {} running, {:.1f} s, ETA {}", bar, finished, p.total,
                     p.skipped, p.failed, p.running, p.elapsed_s, eta);
}

namespace {

nlohmann::json plan_json(const BatchOptions& o, const std::vector<RunSpec>& runs) {
  nlohmann::json j;
  j["executable"] = o.executable;
  j["datasets"] = o.datasets;
  j["configs"] = o.configs;
  j["seeds"] = o.seeds;
  j["duration_s"] = o.duration_s;
  j["extra_args"] = o.extra_args;
  j["jobs"] = o.jobs;
  j["align"] = to_string(o.eval.align);
  j["max_diff_s"] = o.eval.association.max_diff_s;
  j["rpe"] = {{"delta", o.eval.rpe.delta}, {"unit", to_string(o.eval.rpe.unit)}};
  j["eval"] = to_json(o.eval);  // all of them (the three keys above are kept for older readers)
  j["confidence"] = o.confidence;
  nlohmann::json jr = nlohmann::json::array();
  for (const auto& r : runs)
    jr.push_back({{"dataset", r.dataset}, {"config", r.config}, {"seed", r.seed}, {"dir", r.dir}, {"argv", r.argv}});
  j["runs"] = jr;
  return j;
}

// A run's eval.json when it exists and was made with these options (an earlier batch with another alignment or RPE
// delta, or `rtslam report RUN_DIR` with its defaults, leaves one made with others: it is evaluated again).
std::optional<nlohmann::json> current_eval(const RunSpec& run, const EvalOptions& eval) {
  const fs::path path = fs::path(run.dir) / "eval.json";
  if (!fs::exists(path)) return std::nullopt;
  try {
    nlohmann::json j = read_json(path.string());
    if (j.contains("options") && j["options"] == to_json(eval)) return j;
  } catch (const Error&) {
    // unreadable: written again
  }
  return std::nullopt;
}

// Evaluates a finished run into its eval.json; false (and a note in the log) if the evaluation fails.
bool evaluate_into_json(const RunSpec& run, const EvalOptions& eval) {
  try {
    write_run_eval(evaluate_run(run.dir, eval));
    return true;
  } catch (const Error& e) {
    rtslam::logger("eval")->warn("run {} could not be evaluated: {}", run.dir, e.what());
    std::ofstream(fs::path(run.dir) / "eval_error.txt") << e.what() << '\n';
    return false;
  }
}

}  // namespace

std::string write_command_list(const BatchOptions& o, const std::string& path) {
  std::string text;
  for (const auto& r : plan_batch(o)) {
    std::string cmd;
    for (const auto& a : r.argv) {
      if (!cmd.empty()) cmd.push_back(' ');
      cmd.append(shell_quote(a));
    }
    const std::string dir = shell_quote(r.dir);
    text += fmt::format(
        "{{ [ -f {0}/summary.json ] && ! grep -qE '\"status\": \"(interrupted|failed)\"|\"final\": "
        "\"(lost|diverged)\"|\"never_tracked\": true' {0}/summary.json; }} || "
        "{{ mkdir -p {0} && {1} > {0}/run.log 2>&1; }}\n",
        dir, cmd);
  }
  write_text(path, text);
  return path;
}

void write_slurm_script(const BatchOptions& o, const std::string& path, const std::string& commands_path) {
  const auto runs = plan_batch(o);
  const std::string root = absolute(o.out_dir);
  std::string s;
  s += "#!/bin/bash\n";
  s += "# rtslam batch as a Slurm job array: one independent run per array task (generated by rtslam batch).\n";
  s += "# Submit:    sbatch " + shell_quote(absolute(path)) + "\n";
  s += "# Aggregate: rtslam batch --aggregate-only --out " + shell_quote(root) + " (after the array has finished)\n";
  s += "#SBATCH --job-name=rtslam-batch\n";
  s += fmt::format("#SBATCH --array=0-{}\n", runs.size() - 1);
  s += "#SBATCH --ntasks=1\n#SBATCH --cpus-per-task=1\n#SBATCH --time=01:00:00\n";
  s += "#SBATCH --output=" + root + "/slurm/%A_%a.out\n";
  s += "set -euo pipefail\n";
  s += "line=$(sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" " + shell_quote(absolute(commands_path)) + ")\n";
  s += "[ -n \"$line\" ] || { echo \"no command for task $SLURM_ARRAY_TASK_ID\" >&2; exit 1; }\n";
  s += "exec bash -c \"$line\"\n";
  fs::create_directories(fs::path(root) / "slurm");
  write_text(path, s);
  fs::permissions(path, fs::perms::owner_exec | fs::perms::group_exec, fs::perm_options::add);
}

std::string write_batch_plan(const BatchOptions& o, bool replace_matrix) {
  const fs::path root = absolute(o.out_dir);
  fs::create_directories(root);
  const std::string path = (root / "batch_plan.json").string();
  if (!replace_matrix && fs::exists(path)) {
    // A plan of another matrix (an --aggregate-only that left out --dataset, --config or --seeds) is kept: a report
    // made from it later then still covers the runs that exist.
    const BatchOptions stored = load_batch_plan(root.string());
    if (stored.datasets != o.datasets || stored.configs != o.configs || stored.seeds != o.seeds ||
        stored.duration_s != o.duration_s || stored.extra_args != o.extra_args) {
      rtslam::logger("eval")->warn("{} kept: it describes another matrix of runs than this invocation's", path);
      return path;
    }
  }
  write_text(path, plan_json(o, plan_batch(o)).dump(1) + "\n");
  return path;
}

BatchOutcome run_batch(const BatchOptions& o, const std::function<void(const BatchProgress&)>& on_progress) {
  const auto runs = plan_batch(o);
  const fs::path root = absolute(o.out_dir);
  write_batch_plan(o, true);
  write_command_list(o, (root / "commands.txt").string());

  BatchOutcome outcome;
  outcome.total = runs.size();
  BatchProgress progress;
  progress.total = runs.size();
  const auto start = std::chrono::steady_clock::now();
  auto report = [&] {
    progress.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (on_progress) on_progress(progress);
  };

  std::vector<std::size_t> todo;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    if (run_finished(runs[i])) {
      ++progress.skipped;
      if (!current_eval(runs[i], o.eval)) evaluate_into_json(runs[i], o.eval);
    } else {
      todo.push_back(i);
    }
  }
  outcome.skipped = progress.skipped;
  report();

  struct Active {
    std::size_t index;
    ChildProcess child;
  };
  std::vector<Active> active;
  std::size_t next = 0;
  while (next < todo.size() || !active.empty()) {
    while (next < todo.size() && active.size() < static_cast<std::size_t>(o.jobs)) {
      const RunSpec& r = runs[todo[next++]];
      fs::create_directories(r.dir);
      const std::string log = (fs::path(r.dir) / "run.log").string();
      std::error_code ec;
      fs::remove(log, ec);  // a rerun starts a fresh log
      try {
        active.push_back({todo[next - 1], spawn_process(r.argv, log)});
      } catch (const IoError& e) {
        ++progress.failed;
        ++outcome.failed;
        outcome.failed_dirs.push_back(r.dir);
        rtslam::logger("eval")->warn("run {} could not start: {}", r.dir, e.what());
        std::ofstream(log) << e.what() << '\n';
      }
      progress.running = active.size();
      report();
    }
    bool changed = false;
    for (std::size_t k = 0; k < active.size();) {
      int code = 0;
      if (!poll_process(active[k].child, code)) {
        ++k;
        continue;
      }
      const RunSpec& r = runs[active[k].index];
      active.erase(active.begin() + static_cast<std::ptrdiff_t>(k));
      progress.running = active.size();
      if (code == 0 && run_finished(r)) {
        ++progress.done;
        ++outcome.ran;
        evaluate_into_json(r, o.eval);
      } else {
        ++progress.failed;
        ++outcome.failed;
        outcome.failed_dirs.push_back(r.dir);
        rtslam::logger("eval")->warn("run {} failed (exit code {}{}), see {}/run.log", r.dir, code,
                                 code == 0 ? ", no summary.json" : "", r.dir);
      }
      changed = true;
    }
    if (changed) report();
    else std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  report();
  return outcome;
}

namespace {

ErrorStats stats_or_empty(const std::vector<double>& v) { return v.empty() ? ErrorStats{} : compute_stats(v); }

double json_number(const nlohmann::json& j, const std::vector<std::string>& path) {
  const nlohmann::json* p = &j;
  for (const auto& k : path) {
    if (!p->is_object() || !p->contains(k)) return std::nan("");
    p = &(*p)[k];
  }
  return p->is_number() ? p->get<double>() : std::nan("");
}

std::string fmt_num(double v, int prec = 4) {
  return std::isfinite(v) ? fmt::format("{:.{}f}", v, prec) : std::string("-");
}

}  // namespace

std::vector<GroupSummary> aggregate_batch(const BatchOptions& o) {
  const auto runs = plan_batch(o);
  const fs::path root = absolute(o.out_dir);
  write_batch_plan(o, false);  // what was aggregated, for a report later (also after --emit-slurm and --aggregate-only)
  std::map<std::pair<std::string, std::string>, std::size_t> index;
  std::vector<GroupSummary> groups;
  struct Acc {
    std::vector<double> ate_t, ate_r, rpe_t, scale, frame_ms;
    std::vector<NeesSeries> nees;
  };
  std::vector<Acc> acc;
  nlohmann::json runs_json = nlohmann::json::array();
  for (const auto& r : runs) {
    const auto key = std::make_pair(r.dataset, r.config);
    if (!index.count(key)) {
      index[key] = groups.size();
      groups.push_back({});
      groups.back().dataset = r.dataset;
      groups.back().config = r.config;
      acc.emplace_back();
    }
    GroupSummary& g = groups[index[key]];
    Acc& a = acc[index[key]];
    ++g.runs;
    nlohmann::json rj = {{"dataset", r.dataset}, {"config", r.config}, {"seed", r.seed}, {"dir", r.dir}};
    if (!run_finished(r)) {
      ++g.failed;
      rj["status"] = fs::exists(fs::path(r.dir) / "run.log") ? "failed" : "missing";
      runs_json.push_back(rj);
      continue;
    }
    std::optional<nlohmann::json> current = current_eval(r, o.eval);
    if (!current && !evaluate_into_json(r, o.eval)) {
      ++g.failed;
      rj["status"] = "not evaluated";
      runs_json.push_back(rj);
      continue;
    }
    const nlohmann::json e = current ? std::move(*current) : read_json((fs::path(r.dir) / "eval.json").string());
    ++g.evaluated;
    g.run_dirs.push_back(r.dir);
    a.ate_t.push_back(json_number(e, {"ate", "trans_m", "rmse"}));
    a.ate_r.push_back(json_number(e, {"ate", "rot_deg", "rmse"}));
    const double rpe = json_number(e, {"rpe", "trans_m", "rmse"});
    if (std::isfinite(rpe)) a.rpe_t.push_back(rpe);
    const double scale = json_number(e, {"sim3_scale"});
    if (std::isfinite(scale)) a.scale.push_back(scale);
    if (e.contains("nees") && e["nees"].contains("t_ns")) {
      NeesSeries s;
      s.t = e["nees"]["t_ns"].get<std::vector<TimeNs>>();
      s.nees = e["nees"]["values"].get<std::vector<double>>();
      a.nees.push_back(std::move(s));
    }
    const fs::path frames = fs::path(r.dir) / "frames.csv";
    if (fs::exists(frames)) {
      const CsvTable t = read_csv_table(frames.string());
      const auto ms = frame_times_ms(t);
      a.frame_ms.insert(a.frame_ms.end(), ms.begin(), ms.end());
    }
    rj["status"] = "ok";
    rj["ate_trans_rmse_m"] = a.ate_t.back();
    rj["ate_rot_rmse_deg"] = a.ate_r.back();
    if (std::isfinite(rpe)) rj["rpe_trans_rmse_m"] = rpe;
    if (e.contains("nees") && e["nees"].contains("mean")) rj["nees_mean"] = e["nees"]["mean"];
    runs_json.push_back(rj);
  }
  for (std::size_t i = 0; i < groups.size(); ++i) {
    GroupSummary& g = groups[i];
    const Acc& a = acc[i];
    g.ate_trans_rmse = stats_or_empty(a.ate_t);
    g.ate_rot_rmse = stats_or_empty(a.ate_r);
    g.rpe_trans_rmse = stats_or_empty(a.rpe_t);
    g.sim3_scale = stats_or_empty(a.scale);
    if (!a.nees.empty()) {
      g.nees = average_nees(a.nees, o.confidence);
      g.nees_summary = summarize_average_nees(g.nees);
    }
    g.timing = compute_timing(a.frame_ms);
  }

  // batch.md, batch.csv, batch.json
  write_text((root / "batch.md").string(), format_markdown(groups, o));
  std::string csv =
      "dataset,config,runs,evaluated,failed,ate_trans_rmse_mean_m,ate_trans_rmse_median_m,ate_trans_rmse_std_m,"
      "ate_trans_rmse_max_m,ate_rot_rmse_mean_deg,rpe_trans_rmse_mean_m,sim3_scale_mean,nees_runs,nees_mean,"
      "nees_fraction_in_band,nees_band_lo,nees_band_hi,frame_ms_mean,frame_ms_median,frame_ms_p95,frame_ms_max\n";
  nlohmann::json jg = nlohmann::json::array();
  for (const auto& g : groups) {
    const bool has_nees = !g.nees.t.empty();
    // A metric no run has (no RPE, no covariances, no frames.csv, nothing evaluated) is an empty cell, not a 0.
    const auto cell = [](bool known, double v) { return known ? fmt::format("{}", v) : std::string(); };
    const bool ate = g.ate_trans_rmse.n > 0, rpe = g.rpe_trans_rmse.n > 0, scale = g.sim3_scale.n > 0;
    const bool timing = g.timing.frames > 0;
    csv += fmt::format("{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n", g.dataset, g.config, g.runs,
                       g.evaluated, g.failed, cell(ate, g.ate_trans_rmse.mean), cell(ate, g.ate_trans_rmse.median),
                       cell(ate, g.ate_trans_rmse.std), cell(ate, g.ate_trans_rmse.max),
                       cell(g.ate_rot_rmse.n > 0, g.ate_rot_rmse.mean), cell(rpe, g.rpe_trans_rmse.mean),
                       cell(scale, g.sim3_scale.mean), has_nees ? g.nees_summary.n_runs : 0,
                       cell(has_nees, g.nees_summary.mean), cell(has_nees, g.nees_summary.fraction_in_band),
                       cell(has_nees, g.nees_summary.band_lo), cell(has_nees, g.nees_summary.band_hi),
                       cell(timing, g.timing.mean_ms), cell(timing, g.timing.median_ms), cell(timing, g.timing.p95_ms),
                       cell(timing, g.timing.max_ms));
    nlohmann::json j = {{"dataset", g.dataset},
                        {"config", g.config},
                        {"runs", g.runs},
                        {"evaluated", g.evaluated},
                        {"failed", g.failed},
                        {"ate_trans_rmse_m", to_json(g.ate_trans_rmse)},
                        {"ate_rot_rmse_deg", to_json(g.ate_rot_rmse)},
                        {"rpe_trans_rmse_m", to_json(g.rpe_trans_rmse)},
                        {"sim3_scale", to_json(g.sim3_scale)},
                        {"timing", g.timing.frames == 0 ? nlohmann::json({{"frames", 0}})
                                                        : nlohmann::json({{"frames", g.timing.frames},
                                                                          {"mean_ms", g.timing.mean_ms},
                                                                          {"median_ms", g.timing.median_ms},
                                                                          {"p95_ms", g.timing.p95_ms},
                                                                          {"max_ms", g.timing.max_ms}})},
                        {"run_dirs", g.run_dirs}};
    if (has_nees) {
      j["nees"] = to_json(g.nees_summary);
      std::vector<double> t;
      for (TimeNs ti : g.nees.t) t.push_back(to_seconds(ti));
      j["nees"]["t_s"] = t;
      j["nees"]["average"] = g.nees.mean;
      j["nees"]["n_runs"] = g.nees.n_runs;
      j["nees"]["lo"] = g.nees.lo;
      j["nees"]["hi"] = g.nees.hi;
    }
    jg.push_back(j);
  }
  write_text((root / "batch.csv").string(), csv);
  nlohmann::json out = {{"groups", jg}, {"runs", runs_json}, {"plan", plan_json(o, runs)}};
  write_text((root / "batch.json").string(), out.dump(1) + "\n");
  return groups;
}

std::string format_markdown(const std::vector<GroupSummary>& groups, const BatchOptions& o) {
  std::string md;
  md += fmt::format("# rtslam batch: {} dataset(s) x {} config(s) x {} seed(s)\n\n", o.datasets.size(),
                    o.configs.size(), o.seeds.size());
  md += fmt::format("Alignment {}; ATE/RPE: mean (median, std) over runs of each run's RMSE; NEES: average over "
                    "runs of the 6-DoF pose NEES, its mean over time and the fraction of time inside the {:g} % band "
                    "for that number of runs; timing over all frames.\n\n",
                    to_string(o.eval.align), 100.0 * o.confidence);
  md += "| dataset | config | runs ok/all | ATE trans RMSE (m) | ATE rot RMSE (deg) | RPE trans RMSE (m) | "
        "avg NEES | in band | band | frame ms mean / median / p95 |\n";
  md += "|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& g : groups) {
    const bool has_nees = !g.nees.t.empty();
    md += fmt::format(
        "| {} | {} | {}/{} | {} ({}, {}) | {} | {} | {} | {} | {} | {} / {} / {} |\n", g.dataset, g.config,
        g.evaluated, g.runs, fmt_num(g.evaluated ? g.ate_trans_rmse.mean : NAN),
        fmt_num(g.evaluated ? g.ate_trans_rmse.median : NAN), fmt_num(g.evaluated ? g.ate_trans_rmse.std : NAN),
        fmt_num(g.evaluated ? g.ate_rot_rmse.mean : NAN, 3),
        fmt_num(g.rpe_trans_rmse.n ? g.rpe_trans_rmse.mean : NAN),
        has_nees ? fmt_num(g.nees_summary.mean, 2) : "-",
        has_nees ? fmt::format("{:.0f} %", 100.0 * g.nees_summary.fraction_in_band) : "-",
        has_nees ? fmt::format("[{:.2f}, {:.2f}] (N={})", g.nees_summary.band_lo, g.nees_summary.band_hi,
                               g.nees_summary.n_runs)
                 : "-",
        fmt_num(g.timing.frames ? g.timing.mean_ms : NAN, 2), fmt_num(g.timing.frames ? g.timing.median_ms : NAN, 2),
        fmt_num(g.timing.frames ? g.timing.p95_ms : NAN, 2));
  }
  return md;
}

BatchOptions load_batch_plan(const std::string& batch_dir) {
  const fs::path path = fs::path(batch_dir) / "batch_plan.json";
  if (!fs::exists(path)) throw IoError(fmt::format("{}: not a batch directory (no batch_plan.json)", batch_dir));
  const nlohmann::json j = read_json(path.string());
  BatchOptions o;
  try {
    o.out_dir = batch_dir;
    o.executable = j.at("executable").get<std::string>();
    o.datasets = j.at("datasets").get<std::vector<std::string>>();
    o.configs = j.at("configs").get<std::vector<std::string>>();
    o.seeds = j.at("seeds").get<std::vector<std::int64_t>>();
    o.duration_s = j.at("duration_s").get<double>();
    o.extra_args = j.at("extra_args").get<std::vector<std::string>>();
    o.jobs = j.at("jobs").get<int>();
    o.eval.align = parse_alignment(j.at("align").get<std::string>());
    o.eval.association.max_diff_s = j.at("max_diff_s").get<double>();
    o.eval.rpe.delta = j.at("rpe").at("delta").get<double>();
    o.eval.rpe.unit = parse_delta_unit(j.at("rpe").at("unit").get<std::string>());
    if (j.contains("eval")) {  // every evaluation option (plans written since 29 Nov 2026)
      const nlohmann::json& e = j.at("eval");
      o.eval.align = parse_alignment(e.at("align").get<std::string>());
      o.eval.association.max_diff_s = e.at("association").at("max_diff_s").get<double>();
      o.eval.association.offset_s = e.at("association").at("offset_s").get<double>();
      o.eval.association.interpolate = e.at("association").at("interpolate").get<bool>();
      o.eval.association.max_gap_s = e.at("association").at("max_gap_s").get<double>();
      o.eval.with_rpe = e.at("with_rpe").get<bool>();
      o.eval.rpe.delta = e.at("rpe").at("delta").get<double>();
      o.eval.rpe.unit = parse_delta_unit(e.at("rpe").at("unit").get<std::string>());
      o.eval.rpe.all_pairs = e.at("rpe").at("all_pairs").get<bool>();
      o.eval.rpe.rel_delta_tol = e.at("rpe").at("rel_delta_tol").get<double>();
      o.eval.rpe.pairs_from_reference = e.at("rpe").at("pairs_from_reference").get<bool>();
    }
    o.confidence = j.at("confidence").get<double>();
  } catch (const nlohmann::json::exception& e) {
    throw IoError(fmt::format("{}: bad batch plan ({})", path.string(), e.what()));
  }
  return o;
}

}  // namespace rtslam::eval
