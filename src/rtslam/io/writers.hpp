#pragma once
// Output writers of `rtslam run --out DIR`: map.ply, frames.csv, config.yaml, summary.json (trajectory.txt and
// trajectory.csv are in trajectory_io.hpp), the EuRoC ASL folder writer shared with the simulator, and the
// terminal progress line. Every file is written atomically (AtomicFile): under NAME.tmp, renamed to NAME once
// complete and flushed.
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <functional>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>
#include <yaml-cpp/yaml.h>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/io/calibration.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::io {

/// A file written under `PATH.tmp` in the same folder and renamed to PATH by commit() once flushed without error: PATH
/// is absent, the previous file or complete, never a partial file (a full disk, a file-size limit, an exception or a
/// kill during the writing). Write errors throw IoError naming PATH at the next flush() or commit(). Destroyed
/// without commit() (an exception), it closes and removes the .tmp; a killed process leaves the .tmp with what was
/// flushed.
class AtomicFile {
 public:
  /// Opens PATH.tmp (truncating it); throws IoError naming PATH if it cannot.
  explicit AtomicFile(const std::string& path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  std::ostream& stream() { return out_; }
  /// Pushes what was written to the .tmp file; throws IoError naming PATH if a write failed.
  void flush();
  /// Flushes, closes and renames PATH.tmp to PATH (replacing it); throws IoError naming PATH on any failure, and
  /// then removes the .tmp. Once only.
  void commit();
  /// Closes and removes the .tmp (what the destructor does without commit()).
  void discard() noexcept;
  bool committed() const { return committed_; }
  const std::string& path() const { return path_; }
  const std::string& tmp_path() const { return tmp_; }

 private:
  std::string path_;
  std::string tmp_;
  std::ofstream out_;
  bool committed_ = false;
};

/// Writes PATH atomically: `write` fills the stream, then AtomicFile::commit(). Throws IoError naming PATH.
void write_atomically(const std::string& path, const std::function<void(std::ostream&)>& write);

/// One landmark for map.ply: position in W and its 3x3 position covariance.
struct MapPoint {
  std::uint64_t id = 0;
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  std::optional<bool> euclidean;  // the landmark's type (true: Euclidean point, false: AHP), when known
};

/// ASCII PLY: vertex properties `x y z` (m), `sigma_x sigma_y sigma_z` (the 3 standard deviations along W's axes,
/// sqrt of the covariance diagonal, m), `sigma` (sqrt of the largest covariance eigenvalue, m), `id`, and
/// `euclidean` (uchar, 1 Euclidean, 0 AHP) when every point's type is known. MeshLab and CloudCompare read the extra
/// properties as scalar fields.
void write_map_ply(const std::string& path, const std::vector<MapPoint>& points);
/// Reads what write_map_ply wrote (positions, the three sigmas as a diagonal covariance, ids, types when written).
std::vector<MapPoint> read_map_ply(const std::string& path);

/// Per-frame statistics of the SLAM loop (one row of frames.csv).
struct FrameStats {
  TimeNs t = 0;
  int camera = 0;
  int landmarks = 0;         // landmarks in the map
  int predicted_visible = 0; // predicted inside the image
  int searched = 0;          // searched by correlation
  int matched = 0;           // found (ZNCC above threshold)
  int updated = 0;           // used in an EKF correction
  int initialized = 0;       // new landmarks initialized
  int ransac_inliers = 0;    // size of the 1-point RANSAC consensus set
  // Per-stage wall times [ms].
  double t_predict_ms = 0.0;
  double t_match_ms = 0.0;
  double t_ransac_ms = 0.0;
  double t_update_ms = 0.0;
  double t_init_ms = 0.0;
  double t_map_ms = 0.0;
  double t_total_ms = 0.0;
  int refused = 0;           // corrections the filter refused
  double nis = 0.0;          // summed NIS of the matched observations (first prediction), and their number
  int nis_count = 0;
  int health = 0;            // 0 ok, 1 tracking lost, 2 diverged (slam/health.hpp)
  bool reset = false;        // the robot and the map were re-initialized after this frame
  bool budget_hit = false;   // the search's time budget ran out (search/time_budget_ms)
  int budget_skipped = 0;    // visible landmarks left unsearched because of it
  double t_search_ms = 0.0;  // the search's time (RANSAC + active search + their corrections)
  int absolute_updates = 0;  // absolute position/pose fixes applied since the previous frame (and gated out)
  int absolute_rejected = 0;
  int search_fallback = 0;  // of predicted_visible: admitted although their box exceeded max_search_size_px2
  bool zero_velocity = false;  // a zero-velocity update followed the frame (zero_velocity)
};

/// Streams frames.csv: a header line then one row per frame (t in ns, counts, timings in ms), into frames.csv.tmp
/// flushed at least once a second (a killed run leaves the rows so far there); close() renames it to the final
/// name. Destroyed without close(): the .tmp is removed (AtomicFile).
class FramesCsvWriter {
 public:
  explicit FramesCsvWriter(const std::string& path);
  void write(const FrameStats& stats);
  void close();
  FramesCsvWriter(const FramesCsvWriter&) = delete;
  FramesCsvWriter& operator=(const FramesCsvWriter&) = delete;

  static const char* header();

 private:
  AtomicFile file_;
  std::chrono::steady_clock::time_point last_flush_;
};

/// Reads frames.csv back (for tests and reports).
std::vector<FrameStats> read_frames_csv(const std::string& path);

/// config.yaml: the effective configuration, so `rtslam run [run_flags] --config DIR/config.yaml` reproduces the run
/// (run_flags: what else the command needs, e.g. "--points-demo"; named in the file's first line).
void write_config_yaml(const std::string& path, const YAML::Node& config, const std::string& run_flags = "");

/// summary.json (pretty-printed, 2-space indent).
void write_summary_json(const std::string& path, const nlohmann::json& summary);

/// Median and percentiles of a sample (for timing summaries); empty input gives zeros.
struct Percentiles {
  double median = 0.0, p90 = 0.0, p99 = 0.0, max = 0.0, mean = 0.0;
  std::size_t count = 0;
};
Percentiles percentiles(std::vector<double> values);
nlohmann::json to_json(const Percentiles& p);

/// Writes an EuRoC / ASL folder: ROOT/mav0/{camN, imu0, state_groundtruth_estimate0} with data.csv files in the
/// standard headers, PNG images named `<t>.png`, and sensor.yaml files (with `%YAML:1.0`, T_BS = our T_RS). What it
/// writes, the EuRoC reader reads back bit-identically (numbers in shortest round-trip text).
class EurocWriter {
 public:
  /// Creates the folders and writes the sensor.yaml files of `rig` (cameras camN in order, imu0 if present).
  EurocWriter(const std::string& root, const Rig& rig);
  ~EurocWriter();
  EurocWriter(const EurocWriter&) = delete;
  EurocWriter& operator=(const EurocWriter&) = delete;

  /// Writes a CV_8UC1 image as camN/data/<t>.png and its data.csv row.
  void add_image(int camera, TimeNs t, const cv::Mat& image);
  void add_imu(const ImuSample& sample);
  /// state_groundtruth_estimate0/data.csv (p, q, and v/biases when present; zeros where absent).
  void write_ground_truth(const Trajectory& trajectory);
  /// Flushes and closes the data.csv files (also done by the destructor, which swallows errors).
  void close();

 private:
  std::string mav0_;
  std::vector<std::ofstream> cam_csv_;
  std::vector<std::string> cam_csv_path_;
  std::ofstream imu_csv_;
  std::string imu_csv_path_;
  bool closed_ = false;
};

/// A progress line on stderr for long runs: frames done, rate and ETA, redrawn at most 4 times per second, only
/// when the stream is a terminal (silent otherwise, e.g. in CI logs).
class ProgressLine {
 public:
  /// total = 0 when unknown. `stream` defaults to stderr; `enabled` overrides the TTY check.
  explicit ProgressLine(std::size_t total = 0, std::FILE* stream = nullptr, std::optional<bool> enabled = {});
  void update(std::size_t done);
  /// Clears the line (prints a newline after the last state) when enabled.
  void finish();
  bool enabled() const { return enabled_; }
  /// The text of one progress line, e.g. "frames 120/1000 (12%)  30.0 fps  ETA 0:29".
  static std::string format(std::size_t done, std::size_t total, double elapsed_s);

 private:
  std::size_t total_;
  std::FILE* stream_;
  bool enabled_;
  std::size_t done_ = 0;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
  bool drawn_ = false;
};

}  // namespace rtslam::io
