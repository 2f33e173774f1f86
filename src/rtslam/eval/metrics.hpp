#pragma once
// Trajectory error metrics with evo's definitions (evo/core/metrics.py), so that our numbers equal evo's:
//  - ATE (evo APE): after alignment, translation error |p_est − p_gt| (m) and rotation angle of R_estᵀ R_gt (deg);
//  - RPE: for index pairs (i, j), E = (Q_i⁻¹ Q_j)⁻¹ (P_i⁻¹ P_j) with Q ground truth and P the aligned estimate;
//    translation error |t(E)| (m), rotation error angle(E) (deg). Pairs as evo's filters.py (consecutive by
//    default, all_pairs optional), chosen on the aligned estimate (evo's default; or on the reference):
//      frames  — ids 0, δ, 2δ, …;
//      meters  — path length accumulated from pose 0; an id each time it reaches δ (then restarts from 0);
//      seconds — rtslam's extension (evo has none): ids 0, then each first pose at least δ s after the last id.
//  - statistics: rmse, mean, median (mean of the two middle values), std (population), min, max, sse.
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/eval/align.hpp"
#include "rtslam/eval/associate.hpp"

namespace rtslam::eval {

struct ErrorStats {
  std::size_t n = 0;
  double rmse = 0.0, mean = 0.0, median = 0.0, std = 0.0, min = 0.0, max = 0.0, sse = 0.0;
};

/// Statistics of a non-empty error list (throws DataError if empty).
ErrorStats compute_stats(const std::vector<double>& errors);

struct AteResult {
  std::vector<TimeNs> t;
  std::vector<double> trans_err_m;
  std::vector<double> rot_err_deg;
  ErrorStats trans_m;
  ErrorStats rot_deg;
};

/// ATE of an aligned, associated estimate.
AteResult compute_ate(const Trajectory& est_aligned, const Trajectory& gt);

enum class DeltaUnit { Frames, Meters, Seconds };
DeltaUnit parse_delta_unit(const std::string& name);  // "frames" | "m" | "s" (also "meters", "seconds")
std::string to_string(DeltaUnit u);

struct RpeOptions {
  double delta = 1.0;
  DeltaUnit unit = DeltaUnit::Frames;
  bool all_pairs = false;
  double rel_delta_tol = 0.1;         // all_pairs in meters/seconds: accept |Δ − δ| <= rel_delta_tol·δ
  bool pairs_from_reference = false;  // evo default: pairs from the estimate
};

struct RpeResult {
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  std::vector<TimeNs> t;  // time of the second pose of each pair
  std::vector<double> trans_err_m;
  std::vector<double> rot_err_deg;
  ErrorStats trans_m;
  ErrorStats rot_deg;
};

/// Index pairs for RPE on `traj` (see the header comment). Throws DataError when no pair fits.
std::vector<std::pair<std::size_t, std::size_t>> rpe_pairs(const Trajectory& traj, const RpeOptions& options);

/// RPE of an aligned, associated estimate.
RpeResult compute_rpe(const Trajectory& est_aligned, const Trajectory& gt, const RpeOptions& options);

struct EvalOptions {
  Alignment align = Alignment::Se3;
  AssociationOptions association;
  bool with_rpe = true;
  RpeOptions rpe;
};

struct EvalResult {
  std::size_t n_est = 0, n_gt = 0, n_matched = 0;
  Alignment align = Alignment::Se3;
  Sim3 alignment;             // est' = alignment ∘ est
  double sim3_scale = 1.0;    // the Sim(3) Umeyama scale, reported whatever the alignment (monocular scale drift)
  // How well the positions determine the fits (align.hpp, alignment_spread; NaN where there is no such fit): the
  // chosen SE3 / Sim3 alignment's rotation (deg, worst axis) and the Sim(3) scale (relative).
  double alignment_rotation_std_deg = std::numeric_limits<double>::quiet_NaN();
  double sim3_scale_rel_std = std::numeric_limits<double>::quiet_NaN();
  double duration_s = 0.0;    // time span of the associated poses (NaN without timestamps: KITTI)
  double path_length_m = 0.0; // path length of the associated ground truth
  AteResult ate;
  std::optional<RpeResult> rpe;
  std::string rpe_error;      // why RPE is missing (e.g. no pair for this delta)
};

/// Associate, align, compute ATE and (optionally) RPE.
EvalResult evaluate(const Trajectory& est, const Trajectory& gt, const EvalOptions& options);

nlohmann::json to_json(const ErrorStats& s);
/// JSON of the result; with `with_series` the per-pose error arrays are included.
/// Every option of an evaluation (alignment, association, RPE), so that a stored result can be checked against the
/// options asked for before it is reused.
nlohmann::json to_json(const EvalOptions& options);
/// Includes the options (`options`, to_json above).
nlohmann::json to_json(const EvalResult& r, const EvalOptions& options, bool with_series = false);
/// When the alignment says more about the residual than about the run (its rotation or the Sim(3) scale uncertain
/// beyond kMaxAlignmentRotationStdDeg / kMaxAlignmentScaleStd, e.g. over a standstill): one line saying so and what
/// to use instead; else empty.
std::string alignment_warning(const EvalResult& r);
/// A human-readable table for the terminal (with alignment_warning's line when there is one).
std::string format_table(const EvalResult& r, const EvalOptions& options);

}  // namespace rtslam::eval
