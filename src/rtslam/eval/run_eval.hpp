#pragma once
// Evaluation of one run folder written by `rtslam run`:
//   trajectory.csv (estimate with 6x6 covariances; trajectory.txt, TUM, if the CSV is absent),
//   groundtruth.txt (TUM, or groundtruth.csv), frames.csv (per frame: `#timestamp [ns]` or `t_s`, ..., `t_total [ms]` or
//   `time_total_ms`), summary.json.
// Produces ATE/RPE (metrics.hpp), the NEES series (nees.hpp, when covariances are present) and per-frame timing,
// and writes them to RUN_DIR/eval.json.
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/eval/metrics.hpp"
#include "rtslam/eval/nees.hpp"

namespace rtslam::eval {

struct TimingStats {
  std::size_t frames = 0;
  double mean_ms = 0.0, median_ms = 0.0, p95_ms = 0.0, max_ms = 0.0;
};

/// Statistics of a list of per-frame times (empty list: all zero).
TimingStats compute_timing(const std::vector<double>& ms);

/// A numeric CSV with a header line (a leading '#' on the header is allowed): column name → values.
struct CsvTable {
  std::vector<std::string> names;
  std::vector<std::vector<double>> columns;
  /// The column's values, or nullptr if there is no such column.
  const std::vector<double>* column(const std::string& name) const;
};
/// Reads a numeric CSV; throws IoError naming the file and line on a malformed line.
CsvTable read_csv_table(const std::string& path);

/// The per-frame total processing time of a frames.csv table (column `time_total_ms` or `t_total [ms]`), or empty.
std::vector<double> frame_times_ms(const CsvTable& frames);

struct RunEvaluation {
  std::string dir;
  std::string estimate_file, groundtruth_file;
  EvalOptions options;
  EvalResult metrics;
  Trajectory est_aligned;  // associated estimate after the alignment (for plots)
  Trajectory gt;           // associated ground truth
  std::optional<NeesSeries> nees;
  std::optional<NeesSummary> nees_summary;
  std::string nees_note;  // why NEES is missing
  std::vector<double> frame_t_s, frame_time_ms;
  TimingStats timing;
};

/// The estimate file of a run folder (trajectory.csv, else trajectory.txt); throws IoError if neither exists.
std::string find_estimate_file(const std::string& run_dir);
/// The ground-truth file of a run folder (groundtruth.txt, else groundtruth.csv); throws IoError if neither exists.
std::string find_groundtruth_file(const std::string& run_dir);

/// Evaluates a run folder (see the header comment).
RunEvaluation evaluate_run(const std::string& run_dir, const EvalOptions& options);

/// JSON of a run evaluation; with `with_series` the per-pose errors and NEES series are included.
nlohmann::json to_json(const RunEvaluation& r, bool with_series);

/// Writes RUN_DIR/eval.json (with series) and returns its path.
std::string write_run_eval(const RunEvaluation& r);

/// The accuracy a run reports when a reference trajectory is at hand (rtslam run's summary), with the ground truth
/// interpolated at the estimate's timestamps. A run with metric scale (inertial, stereo) reports the SE(3)-aligned
/// ATE, the scale error |s − 1| of the Sim(3) alignment (which an SE(3) ATE alone would not show, and a Sim(3) ATE
/// would hide) and the translational RPE over 10 m of path; a monocular run, whose scale is not observable, the
/// Sim(3)-aligned ATE as a percentage of the path. With covariances, the pose NEES (first-pose aligned).
struct RunAccuracy {
  bool metric_scale = false;
  EvalOptions options;
  EvalResult ate;                    // SE(3) (metric scale) or Sim(3) alignment
  double scale_error = 0.0;          // |s − 1| of the Sim(3) alignment
  std::optional<RpeResult> rpe_10m;  // metric scale: translation error per 10 m of path, when the path is long enough
  std::optional<NeesSummary> nees;
  std::string line;                  // one printable line (with a trailing newline)
  nlohmann::json json;
};
RunAccuracy evaluate_accuracy(const Trajectory& est, const Trajectory& gt, bool metric_scale);

}  // namespace rtslam::eval
