#include "rtslam/viz/replay.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/io/text.hpp"
#include "rtslam/io/trajectory_io.hpp"
#include "rtslam/io/writers.hpp"

namespace fs = std::filesystem;

namespace rtslam::viz {

std::vector<LandmarkReport> read_map_ply(const std::string& path, bool* types_known) {
  io::LineReader in(path);
  std::string line;
  std::size_t count = 0;
  std::vector<std::string> props;
  bool in_vertex = false, header_done = false;
  while (!header_done && in.next(line)) {
    const auto f = io::split(line, ' ');
    if (in.line_number() == 1 && line != "ply") throw IoError(fmt::format("{}:1: not a PLY file", path));
    if (in.line_number() == 2 && line != "format ascii 1.0") {
      throw IoError(fmt::format("{}:2: only ASCII PLY is read (found '{}')", path, line));
    }
    if (f.size() == 3 && f[0] == "element") {
      in_vertex = f[1] == "vertex";
      if (in_vertex) {
        std::int64_t n = 0;
        if (!io::parse_int64(f[2], n) || n < 0) {
          throw IoError(fmt::format("{}:{}: bad vertex count", path, in.line_number()));
        }
        count = static_cast<std::size_t>(n);
      }
    } else if (f.size() == 3 && f[0] == "property" && in_vertex) {
      props.emplace_back(f[2]);
    }
    header_done = line == "end_header";
  }
  if (!header_done) throw IoError(fmt::format("{}: no end_header", path));
  const auto col = [&](const char* name) -> int {
    const auto it = std::find(props.begin(), props.end(), name);
    return it == props.end() ? -1 : static_cast<int>(it - props.begin());
  };
  const int cx = col("x"), cy = col("y"), cz = col("z"), csx = col("sigma_x"), csy = col("sigma_y"),
            csz = col("sigma_z"), cid = col("id"), ceu = col("euclidean");
  if (cx < 0 || cy < 0 || cz < 0) throw IoError(fmt::format("{}: the vertices have no x y z", path));
  if (types_known) *types_known = ceu >= 0;
  std::vector<LandmarkReport> out;
  out.reserve(count);
  while (out.size() < count && in.next(line)) {
    const auto f = io::split(line, ' ');
    if (f.size() != props.size()) {
      throw IoError(fmt::format("{}:{}: {} values for {} properties", path, in.line_number(), f.size(), props.size()));
    }
    const auto num = [&](int c, double fallback) {
      double v = fallback;
      if (c >= 0 && !io::parse_double(f[static_cast<std::size_t>(c)], v)) {
        throw IoError(fmt::format("{}:{}: bad number '{}'", path, in.line_number(), f[static_cast<std::size_t>(c)]));
      }
      return v;
    };
    LandmarkReport l;
    l.p_W = {num(cx, 0), num(cy, 0), num(cz, 0)};
    const Eigen::Vector3d sd(num(csx, 0), num(csy, 0), num(csz, 0));
    l.cov_W = sd.cwiseAbs2().asDiagonal();
    l.id = static_cast<int>(num(cid, static_cast<double>(out.size())));
    l.euclidean = num(ceu, 0) != 0.0;
    out.push_back(std::move(l));
  }
  if (out.size() != count) throw IoError(fmt::format("{}: {} vertices announced, {} read", path, count, out.size()));
  return out;
}

std::vector<OverlayIndexRow> read_overlay_index(const std::string& path) {
  io::LineReader in(path);
  std::string line;
  std::vector<OverlayIndexRow> rows;
  while (in.next(line)) {
    if (in.line_number() == 1) continue;  // header
    if (io::trim(line).empty()) continue;
    const auto f = io::split(line, ',');
    if (f.size() != 11) {
      throw IoError(fmt::format("{}:{}: expected 11 fields, found {}", path, in.line_number(), f.size()));
    }
    std::int64_t v[11] = {};
    double nis_sum = 0.0;
    bool ok = true;
    for (int k : {0, 1, 3, 4, 5, 6, 7, 8, 10}) ok = ok && io::parse_int64(f[static_cast<std::size_t>(k)], v[k]);
    ok = ok && io::parse_double(f[9], nis_sum);
    if (!ok) throw IoError(fmt::format("{}:{}: bad number", path, in.line_number()));
    OverlayIndexRow r;
    r.index = static_cast<int>(v[0]);
    r.t = v[1];
    r.file = std::string(f[2]);
    // A file of the overlays folder itself (the writer's overlay_NNNNN.png): a path elsewhere would be served.
    if (r.file.empty() || r.file == "." || r.file == ".." || r.file.find_first_of("/\\") != std::string::npos) {
      throw IoError(fmt::format("{}:{}: '{}' is not a file name in the overlays folder", path, in.line_number(),
                                r.file));
    }
    r.stats.t = r.t;
    r.stats.visible = static_cast<int>(v[3]);
    r.stats.searched = static_cast<int>(v[4]);
    r.stats.matched = static_cast<int>(v[5]);
    r.stats.ransac_inliers = static_cast<int>(v[6]);
    r.stats.updated = static_cast<int>(v[7]);
    r.stats.initialized = static_cast<int>(v[8]);
    r.nis.sum = nis_sum;
    r.nis.count = static_cast<int>(v[10]);
    rows.push_back(std::move(r));
  }
  return rows;
}

namespace {

slam::FrameStats from_io(const io::FrameStats& f) {
  slam::FrameStats s;
  s.t = f.t;
  s.landmarks_in_map = f.landmarks;
  s.visible = f.predicted_visible;
  s.searched = f.searched;
  s.matched = f.matched;
  s.updated = f.updated;
  s.initialized = f.initialized;
  s.ransac_inliers = f.ransac_inliers;
  s.time_predict_ms = f.t_predict_ms;
  s.time_match_ms = f.t_match_ms;
  s.time_ransac_ms = f.t_ransac_ms;
  s.time_update_ms = f.t_update_ms;
  s.time_init_ms = f.t_init_ms;
  s.time_map_ms = f.t_map_ms;
  s.time_total_ms = f.t_total_ms;
  s.budget_hit = f.budget_hit;
  s.budget_skipped = f.budget_skipped;
  s.time_search_ms = f.t_search_ms;
  s.fallback = f.search_fallback;
  return s;
}

}  // namespace

RunRecording load_run(const std::string& dir, const std::string& overlays_dir) {
  RunRecording rec;
  rec.dir = dir;
  const fs::path root(dir);
  if (!fs::is_directory(root)) throw IoError(fmt::format("{}: not a folder", dir));
  const fs::path traj = root / "trajectory.csv";
  if (!fs::exists(traj)) {
    throw IoError(fmt::format("{}: not an rtslam run output folder (no trajectory.csv; see docs/outputs.md)", dir));
  }
  const Trajectory est = io::read_trajectory(traj.string());

  std::vector<io::FrameStats> frames;
  if (fs::exists(root / "frames.csv")) frames = io::read_frames_csv((root / "frames.csv").string());
  std::map<TimeNs, const io::FrameStats*> frame_at;
  for (const auto& f : frames) frame_at[f.t] = &f;

  if (fs::exists(root / "summary.json")) {
    std::ifstream in(root / "summary.json");
    try {
      rec.summary = nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception& e) {
      throw IoError(fmt::format("{}: bad JSON ({})", (root / "summary.json").string(), e.what()));
    }
  }
  rec.title = fs::absolute(root).lexically_normal().filename().string();
  if (rec.title.empty()) rec.title = dir;
  if (rec.summary.is_object() && rec.summary.contains("dataset") && rec.summary["dataset"].is_object()) {
    const auto& d = rec.summary["dataset"];
    rec.title = fmt::format("{} ({})", d.value("name", std::string("?")), d.value("kind", std::string("?")));
    if (rec.summary.contains("seed")) rec.title += fmt::format(", seed {}", rec.summary["seed"].dump());
  }

  // Overlays: the given folder, or DIR/overlays.
  fs::path ov = overlays_dir.empty() ? root / "overlays" : fs::path(overlays_dir);
  std::map<TimeNs, const OverlayIndexRow*> overlay_at;
  std::vector<OverlayIndexRow> overlay_rows;
  if (fs::exists(ov / "index.csv")) {
    overlay_rows = read_overlay_index((ov / "index.csv").string());
    rec.overlays_dir = ov.string();
    for (const auto& r : overlay_rows) {
      overlay_at[r.t] = &r;
      rec.overlays.push_back(OverlayFrame{r.index, r.t, (ov / r.file).string()});
    }
    std::sort(rec.overlays.begin(), rec.overlays.end(),
              [](const OverlayFrame& a, const OverlayFrame& b) { return a.index < b.index; });
    if (!rec.overlays.empty()) {
      const cv::Mat first = io::codecs::imread(rec.overlays.front().path, cv::IMREAD_UNCHANGED);
      if (!first.empty()) {
        rec.camera.width = first.cols;
        rec.camera.height = first.rows;
      }
    }
  } else if (!overlays_dir.empty()) {
    throw IoError(fmt::format("{}: no index.csv (not an overlay folder of rtslam run --overlays)", overlays_dir));
  }

  rec.history.reserve(est.poses.size());
  for (std::size_t i = 0; i < est.poses.size(); ++i) {
    const StampedPose& p = est.poses[i];
    HistoryEntry h;
    h.index = static_cast<int>(i);
    h.t = p.t;
    h.T_WR.p = p.p_WR;
    h.T_WR.q = p.q_WR;
    h.cov = p.cov;
    if (const auto it = frame_at.find(p.t); it != frame_at.end()) {
      h.stats = from_io(*it->second);
      h.has_stats = true;
      h.has_timing = true;
    }
    if (const auto it = overlay_at.find(p.t); it != overlay_at.end()) {
      h.index = it->second->index;
      h.nis = it->second->nis;
      if (!h.has_stats) {
        h.stats = it->second->stats;
        h.has_stats = true;
      }
    }
    rec.history.push_back(h);
  }

  if (fs::exists(root / "groundtruth.txt")) {
    rec.ground_truth = io::read_trajectory((root / "groundtruth.txt").string());
    NeesTracker nees(*rec.ground_truth);
    for (auto& h : rec.history) h.nees = nees.nees(h);
  }
  if (fs::exists(root / "map.ply")) rec.map = read_map_ply((root / "map.ply").string(), &rec.map_types_known);
  logger("viz")->info("{}: {} poses, {} landmarks, {} overlays{}", dir, rec.history.size(), rec.map.size(),
                      rec.overlays.size(), rec.ground_truth ? ", ground truth" : "");
  return rec;
}

}  // namespace rtslam::viz
