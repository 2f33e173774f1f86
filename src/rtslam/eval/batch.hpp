#pragma once
// Monte Carlo batches: a matrix datasets × configs × seeds of independent `rtslam run` processes, run `jobs` at a
// time on this machine (resumable: a run whose summary.json exists is not redone), each evaluated into its
// eval.json, then aggregated per (dataset, config) into BATCH_DIR/batch.{md,csv,json}. The same runs can be spread
// over a cluster with the generated command list (GNU parallel) or Slurm job-array script; see docs/evaluation.md.
//
// Layout: BATCH_DIR/runs/<dataset>/<config>/seed_<NNNN>/ (run output + run.log + eval.json),
//         BATCH_DIR/batch_plan.json, commands.txt, batch.md, batch.csv, batch.json.
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "rtslam/eval/metrics.hpp"
#include "rtslam/eval/nees.hpp"
#include "rtslam/eval/run_eval.hpp"

namespace rtslam::eval {

struct BatchOptions {
  std::string out_dir;                         // BATCH_DIR
  std::string executable;                      // the rtslam binary that provides `run`
  std::vector<std::string> datasets{"sim"};    // "sim" = the built-in simulated demo (no --dataset)
  std::vector<std::string> configs{"default"}; // "default" = no --config
  std::vector<std::int64_t> seeds{0};
  double duration_s = 0.0;                     // > 0: passed as --duration
  std::vector<std::string> extra_args;         // appended to every run command
  int jobs = 2;                                // concurrent processes
  EvalOptions eval;                            // evaluation of each run
  double confidence = 0.99;                    // NEES band
};

/// One planned run.
struct RunSpec {
  std::string dataset, config;
  std::int64_t seed = 0;
  std::string dir;                // absolute run directory
  std::vector<std::string> argv;  // the full command
};

/// A filesystem-friendly label: "sim", "default", or the file's stem with other characters as '_'.
std::string label_of(const std::string& spec);

/// The runs of the matrix, in dataset, config, seed order. Throws ConfigError on an empty axis, duplicate seeds
/// or labels that collide.
std::vector<RunSpec> plan_batch(const BatchOptions& options);

/// A run is finished when its summary.json exists.
bool run_finished(const RunSpec& run);

struct BatchProgress {
  std::size_t total = 0, done = 0, skipped = 0, failed = 0, running = 0;
  double elapsed_s = 0.0;
};

struct BatchOutcome {
  std::size_t total = 0, skipped = 0, ran = 0, failed = 0;
  std::vector<std::string> failed_dirs;
};

/// Runs the missing runs (`jobs` at a time) and evaluates every finished run that has no eval.json made with
/// `options.eval` yet.
/// `on_progress` is called after every change. Writes batch_plan.json and commands.txt first.
BatchOutcome run_batch(const BatchOptions& options, const std::function<void(const BatchProgress&)>& on_progress);

/// A progress bar line: "[#####.....]  10/20 done, 0 failed, 2 running, 12.3 s, ETA 10 s".
std::string format_progress(const BatchProgress& p, int width = 30);

/// Per-(dataset, config) aggregate of the finished runs.
struct GroupSummary {
  std::string dataset, config;
  std::size_t runs = 0, evaluated = 0, failed = 0;
  ErrorStats ate_trans_rmse;   // over runs, of each run's ATE RMSE (m)
  ErrorStats ate_rot_rmse;     // (deg)
  ErrorStats rpe_trans_rmse;   // (m), runs with RPE only
  ErrorStats sim3_scale;
  AverageNees nees;            // averaged over the runs with NEES
  NeesSummary nees_summary;
  TimingStats timing;          // over all frames of all runs
  std::vector<std::string> run_dirs;
};

/// Reads every run's eval.json (evaluating runs that lack one made with `options.eval`) and writes batch.md, batch.csv,
/// batch.json and batch_plan.json.
std::vector<GroupSummary> aggregate_batch(const BatchOptions& options);

/// The Markdown table of the groups (as in batch.md).
std::string format_markdown(const std::vector<GroupSummary>& groups, const BatchOptions& options);

/// Writes the shell command list (one run per line, skipping finished runs when executed) and returns its path.
std::string write_command_list(const BatchOptions& options, const std::string& path);

/// Writes a Slurm job-array script running line $SLURM_ARRAY_TASK_ID+1 of the command list (one run per task).
void write_slurm_script(const BatchOptions& options, const std::string& path, const std::string& commands_path);

/// Writes BATCH_DIR/batch_plan.json (the matrix and the evaluation options) and returns its path. run_batch and the
/// command-list / Slurm emitters define the matrix (`replace_matrix`); aggregate_batch keeps a stored plan of another
/// matrix (an --aggregate-only that left out part of it) with a warning.
std::string write_batch_plan(const BatchOptions& options, bool replace_matrix);

/// Reads BATCH_DIR/batch_plan.json back into options (to aggregate or report a batch later).
BatchOptions load_batch_plan(const std::string& batch_dir);

}  // namespace rtslam::eval
