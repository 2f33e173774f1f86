#pragma once
// Reading and writing trajectories (rtslam::Trajectory, poses T_WR of the robot frame R in the world W).
//
// Formats:
//  - Tum: text lines `t x y z qx qy qz qw` (t in seconds, '#' comment lines, blank lines skipped). Written with
//    t to exactly 9 decimals (exact ns) and one leading '#' comment line, as evo and rpg_trajectory_evaluation read.
//  - EurocCsv: EuRoC state CSV `t[ns], p(3), q(w x y z), [v(3), b_w(3), b_a(3)]`, with the original
//    `#timestamp, p_RS_R_x [m], ...` header, the `#time(ns),px,...` variant or no header at all; and rtslam's own
//    trajectory.csv (same columns, velocity/bias groups only when present, then 21 `cov_ij` columns: the upper
//    triangle, row-major, of the 6x6 [δp δθ] pose covariance in the convention of core/trajectory.hpp).
//  - Kitti: 12 numbers per line, the 3x4 row-major [R|t]; no timestamps (has_timestamps = false, t = index).
// Quaternions are stored exactly as read (not renormalized, so that files round-trip bit-identically); readers
// reject a quaternion whose norm is off by more than 1e-2 and a KITTI rotation that is not orthonormal (1e-3).
// KITTI rotations are read as the nearest unit quaternion, and written from the normalized quaternion.
// Errors (IoError for unreadable/malformed files, DataError for bad values) name the file and the line.
#include <chrono>
#include <optional>
#include <string>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/io/writers.hpp"

namespace rtslam::io {

enum class TrajectoryFormat { Auto, Tum, EurocCsv, Kitti };

/// Reads a trajectory file; Auto detects the format from the extension and the first data line.
Trajectory read_trajectory(const std::string& path, TrajectoryFormat format = TrajectoryFormat::Auto);

/// Detects the format of a trajectory file (never returns Auto); throws IoError if it cannot tell.
TrajectoryFormat detect_trajectory_format(const std::string& path);

// Every writer writes atomically (io::AtomicFile): under PATH.tmp, renamed to PATH once complete and flushed.

/// TUM text: `# timestamp[s] tx ty tz qx qy qz qw` then one 8-column line per pose (seconds with 9 decimals).
void write_tum(const std::string& path, const Trajectory& trajectory);

/// rtslam trajectory.csv (EuRoC state style + covariance); the column groups written are those the FIRST pose has
/// (velocity, biases, covariance) and every pose must have the same groups (DataError otherwise).
void write_trajectory_csv(const std::string& path, const Trajectory& trajectory);

/// The same file, streamed pose by pose into PATH.tmp (flushed at least once a second: a killed run leaves the poses
/// so far there); close() renames it to PATH. The header follows the first pose's groups. Destroyed without close():
/// the .tmp is removed.
class TrajectoryCsvWriter {
 public:
  explicit TrajectoryCsvWriter(const std::string& path);
  void write(const StampedPose& pose);
  void close();
  std::size_t rows() const { return rows_; }

 private:
  void write_header_only();
  AtomicFile file_;
  std::optional<StampedPose> first_;
  std::size_t rows_ = 0;
  std::string row_;
  std::chrono::steady_clock::time_point last_flush_;
};

/// KITTI poses: 12 numbers per line (3x4 row-major [R|t]); timestamps are not written.
void write_kitti(const std::string& path, const Trajectory& trajectory);

}  // namespace rtslam::io
