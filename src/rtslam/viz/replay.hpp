#pragma once
// A finished run read back from its output folder (`rtslam run --out DIR`, docs/outputs.md) for `rtslam view`:
// trajectory.csv (poses and covariances), frames.csv (per-frame counts and timings), groundtruth.txt (if any),
// map.ply (the final map), summary.json, and the overlays of `--overlays` (OverlayWriter's PNGs and index.csv).
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/viz/history.hpp"
#include "rtslam/viz/report.hpp"

namespace rtslam::viz {

struct OverlayFrame {
  int index = 0;
  TimeNs t = 0;
  std::string path;  // PNG
};

struct RunRecording {
  std::string dir;
  std::string title;                      // e.g. "euroc-v101 (euroc), seed 1" from summary.json, else the folder
  std::vector<HistoryEntry> history;      // one per processed frame; NEES filled when there is a ground truth
  std::optional<Trajectory> ground_truth;
  std::vector<LandmarkReport> map;        // the final map
  bool map_types_known = false;           // map.ply carries AHP/Euclidean (property `euclidean`); else unknown
  nlohmann::json summary;                 // summary.json, or null
  std::vector<OverlayFrame> overlays;     // sorted by index; empty without overlays
  std::string overlays_dir;               // where they were found ("" if none)
  CameraInfo camera;                      // size from the first overlay (intrinsics unknown: zero)
};

/// Reads a run's output folder. `overlays_dir` empty: DIR/overlays when it exists. Throws IoError naming the file
/// when DIR has no trajectory.csv or a file is malformed; a missing optional file (frames.csv, groundtruth.txt,
/// map.ply, summary.json, overlays) is skipped.
RunRecording load_run(const std::string& dir, const std::string& overlays_dir = "");

/// map.ply of any rtslam version: x y z (m), sigma_x sigma_y sigma_z (m, as a diagonal covariance), id, and the
/// optional uchar `euclidean` (1: Euclidean point, 0: AHP). `types_known` tells whether that property is there.
std::vector<LandmarkReport> read_map_ply(const std::string& path, bool* types_known = nullptr);

/// OverlayWriter's index.csv.
struct OverlayIndexRow {
  int index = 0;
  TimeNs t = 0;
  std::string file;
  slam::FrameStats stats;  // counts only
  Nis nis;
};
std::vector<OverlayIndexRow> read_overlay_index(const std::string& path);

}  // namespace rtslam::viz
