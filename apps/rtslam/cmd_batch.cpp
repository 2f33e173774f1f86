// rtslam batch: a matrix datasets x configs x seeds of independent `rtslam run` processes, -j at a time, resumable,
// evaluated and aggregated (batch.md/csv/json); or the same matrix as a command list / Slurm job-array script.
#include <iostream>
#include <memory>
#include <unistd.h>

#include <fmt/format.h>

#include "commands.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/eval/batch.hpp"
#include "rtslam/eval/process.hpp"
#include "rtslam/eval/report.hpp"

namespace rtslam::cli {

namespace {

struct BatchArgs {
  std::string out, exe, emit_slurm, emit_commands, align = "se3", delta_unit = "frames";
  std::vector<std::string> datasets, configs, run_args;
  std::vector<std::int64_t> seed_list;
  int seeds = 0;
  std::int64_t first_seed = 0;
  double duration = 0.0, delta = 1.0;
  int jobs = 2;
  bool aggregate_only = false, report = false;
};

void run_batch_cmd(const BatchArgs& a) {
  eval::BatchOptions o;
  o.out_dir = a.out;
  o.executable = a.exe.empty() ? eval::self_executable() : a.exe;
  if (!a.datasets.empty()) o.datasets = a.datasets;
  if (!a.configs.empty()) o.configs = a.configs;
  if (!a.seed_list.empty()) {
    o.seeds = a.seed_list;
  } else {
    if (a.seeds < 1) throw ConfigError(fmt::format("--seeds must be >= 1, got {}", a.seeds));
    o.seeds.clear();
    for (int i = 0; i < a.seeds; ++i) o.seeds.push_back(a.first_seed + i);
  }
  o.duration_s = a.duration;
  o.extra_args = a.run_args;
  o.jobs = a.jobs;
  o.eval.align = eval::parse_alignment(a.align);
  o.eval.rpe.delta = a.delta;
  o.eval.rpe.unit = eval::parse_delta_unit(a.delta_unit);
  const auto runs = eval::plan_batch(o);  // validates

  if (!a.emit_slurm.empty() || !a.emit_commands.empty()) {
    const std::string commands =
        a.emit_commands.empty() ? (std::filesystem::path(a.out) / "commands.txt").string() : a.emit_commands;
    eval::write_batch_plan(o, true);  // for --aggregate-only and --report once the runs are done
    eval::write_command_list(o, commands);
    std::cout << fmt::format("wrote {} ({} runs, one per line; e.g. parallel -j N < {})\n", commands, runs.size(),
                             commands);
    if (!a.emit_slurm.empty()) {
      eval::write_slurm_script(o, a.emit_slurm, commands);
      std::cout << fmt::format("wrote {} (sbatch {}; then rtslam batch --aggregate-only with the same matrix)\n",
                               a.emit_slurm, a.emit_slurm);
    }
    return;
  }
  if (!a.aggregate_only) {
    const bool tty = ::isatty(STDERR_FILENO);
    std::size_t last_finished = static_cast<std::size_t>(-1);
    const auto outcome = eval::run_batch(o, [&](const eval::BatchProgress& p) {
      const std::size_t finished = p.done + p.skipped + p.failed;
      if (tty) {
        std::cerr << '\r' << eval::format_progress(p) << std::flush;
      } else if (finished != last_finished) {
        std::cerr << eval::format_progress(p) << '\n';
      }
      last_finished = finished;
    });
    if (tty) std::cerr << '\n';
    std::cout << fmt::format("batch: {} runs, {} resumed, {} ran, {} failed\n", outcome.total, outcome.skipped,
                             outcome.ran, outcome.failed);
    for (const auto& d : outcome.failed_dirs) std::cout << "  failed: " << d << "/run.log\n";
  }
  const auto groups = eval::aggregate_batch(o);
  std::cout << eval::format_markdown(groups, o);
  std::cout << fmt::format("wrote {0}/batch.md, {0}/batch.csv, {0}/batch.json\n", a.out);
  if (a.report) {
    eval::ReportOptions ro;
    const std::string written = eval::write_batch_report(a.out, ro);
    std::cout << "wrote " << written << '\n';
  }
  // From the aggregation, not this invocation's runs: a resumed or --aggregate-only batch with failed runs says so.
  std::size_t failed = 0;
  for (const auto& g : groups) failed += g.failed;
  if (failed > 0) {
    throw DataError(fmt::format("{} of the batch's runs failed or ended broken (their run.log in {}/); the aggregates "
                                "above are of the others", failed, a.out));
  }
}

}  // namespace

void register_batch(CLI::App& app) {
  auto a = std::make_shared<BatchArgs>();
  auto* sub = app.add_subcommand("batch", "Run a matrix of datasets x configs x seeds and aggregate the results");
  sub->add_option("--out", a->out, "batch directory (runs/, batch.md, batch.csv, batch.json)")->required();
  sub->add_option("--seeds", a->seeds, "number of seeds (first-seed, first-seed+1, ...)")->default_val(1);
  sub->add_option("--first-seed", a->first_seed, "first seed")->capture_default_str();
  sub->add_option("--seed-list", a->seed_list, "explicit seeds (instead of --seeds)")->delimiter(',');
  sub->add_option("--dataset", a->datasets, "dataset spec passed to rtslam run --dataset (repeatable; default: "
                                            "the built-in simulation)");
  sub->add_option("--config", a->configs, "config file passed to rtslam run --config (repeatable)");
  sub->add_option("--duration", a->duration, "run duration in s (passed to rtslam run --duration)");
  sub->add_option("--run-arg", a->run_args, "extra argument for every rtslam run (repeatable)")->allow_extra_args(false);
  sub->add_option("-j,--jobs", a->jobs, "concurrent runs")->capture_default_str();
  sub->add_option("--align", a->align, "ATE alignment: se3, sim3, posyaw, origin or none")->capture_default_str();
  sub->add_option("--delta", a->delta, "RPE delta")->capture_default_str();
  sub->add_option("--delta-unit", a->delta_unit, "RPE delta unit: frames, m or s")->capture_default_str();
  sub->add_option("--exe", a->exe, "rtslam executable providing `run` (default: this one)");
  sub->add_option("--emit-slurm", a->emit_slurm, "write a Slurm job-array script instead of running");
  sub->add_option("--emit-commands", a->emit_commands, "write the run command list (GNU parallel) instead of running");
  sub->add_flag("--aggregate-only", a->aggregate_only, "only evaluate finished runs and aggregate");
  sub->add_flag("--report", a->report, "also write the HTML report (BATCH_DIR/report.html)");
  sub->callback([a] { run_batch_cmd(*a); });
}

}  // namespace rtslam::cli
