#pragma once
// `rtslam report`: one self-contained HTML page (figures inlined as SVG; PNG copies written beside them) with the
// paper's figures, drawn by gnuplot (plot.hpp):
//  run:   estimate vs ground truth per axis and per angle over time (paper Fig. 3/5), errors with their 99 %
//         (±2.57σ) confidence area (Fig. 4), NEES over time with its χ² band (Fig. 6), top view, ATE over time,
//         per-frame timing histogram;
//  batch: the aggregate table, average NEES over the runs with the N-run band (Fig. 6), the one-run NEES of every
//         run, ATE RMSE over seeds, top view of all runs, timing histogram of all frames.
#include <string>

#include "rtslam/eval/metrics.hpp"

namespace rtslam::eval {

struct ReportOptions {
  EvalOptions eval;           // for run reports (batch reports use the batch plan's options)
  std::string output;         // HTML path; default DIR/report.html
  double confidence = 0.99;
};

/// True if DIR is a batch directory (has batch_plan.json).
bool is_batch_dir(const std::string& dir);

/// Writes the report of a run or batch directory; returns the HTML path. Figures go to DIR/report_files/.
std::string write_report(const std::string& dir, const ReportOptions& options);

/// The run report (see the header comment).
std::string write_run_report(const std::string& run_dir, const ReportOptions& options);

/// The batch report; aggregates the batch first (batch.md/csv/json are rewritten).
std::string write_batch_report(const std::string& batch_dir, const ReportOptions& options);

}  // namespace rtslam::eval
