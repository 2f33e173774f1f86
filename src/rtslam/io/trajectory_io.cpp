#include "rtslam/io/trajectory_io.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <chrono>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/io/text.hpp"
#include "rtslam/io/writers.hpp"

namespace rtslam::io {
namespace {

bool is_comment_or_blank(std::string_view line) {
  line = trim(line);
  return line.empty() || line.front() == '#' || line.front() == '%';
}

/// Parses every field as a double; on failure throws IoError naming the file, line and field.
std::vector<double> parse_numbers(const std::vector<std::string_view>& fields, size_t first, const std::string& path,
                                  int line) {
  std::vector<double> values(fields.size() - first);
  for (size_t i = first; i < fields.size(); ++i) {
    if (!parse_double(fields[i], values[i - first])) {
      throw IoError(fmt::format("{}:{}: field {} '{}' is not a number", path, line, i + 1, fields[i]));
    }
  }
  return values;
}

// `first_field`: the 1-based field number of v[0] on its line.
void check_finite(const std::vector<double>& v, const std::string& path, int line, size_t first_field = 2) {
  for (size_t i = 0; i < v.size(); ++i) {
    if (!std::isfinite(v[i])) {
      throw DataError(fmt::format("{}:{}: non-finite value in field {}", path, line, i + first_field));
    }
  }
}

Eigen::Quaterniond quat_wxyz(double w, double x, double y, double z, const std::string& path, int line) {
  const double n = std::sqrt(w * w + x * x + y * y + z * z);
  if (!(std::abs(n - 1.0) < 1e-2)) {
    throw DataError(fmt::format("{}:{}: quaternion norm {} is not 1", path, line, n));
  }
  return Eigen::Quaterniond(w, x, y, z);
}

void check_increasing(const Trajectory& traj, TimeNs t, const std::string& path, int line) {
  if (!traj.poses.empty() && t <= traj.poses.back().t) {
    throw DataError(fmt::format("{}:{}: timestamp {} is not after the previous one {}{}", path, line,
                                format_seconds(t), format_seconds(traj.poses.back().t),
                                t == traj.poses.back().t ? " (duplicate)" : " (goes backwards)"));
  }
}

Trajectory read_tum(const std::string& path) {
  Trajectory traj;
  traj.source = path;
  LineReader in(path);
  std::string line;
  while (in.next(line)) {
    if (is_comment_or_blank(line)) continue;
    const auto f = split(line, ' ');
    if (f.size() != 8) {
      throw IoError(fmt::format("{}:{}: expected 8 columns 't x y z qx qy qz qw', found {}", path, in.line_number(),
                                f.size()));
    }
    StampedPose pose;
    if (!parse_seconds(f[0], pose.t)) {
      // A long integer is a time in nanoseconds (ORB-SLAM writes EuRoC's stamps so): TUM files hold seconds.
      const bool integer =
          !f[0].empty() && std::all_of(f[0].begin(), f[0].end(), [](char c) { return c >= '0' && c <= '9'; });
      if (integer && f[0].size() > 10) {
        throw IoError(fmt::format("{}:{}: timestamp '{}' is not in seconds (a {}-digit integer: nanoseconds?); a TUM "
                                  "trajectory holds seconds, e.g. {}.{}",
                                  path, in.line_number(), f[0], f[0].size(), f[0].substr(0, f[0].size() - 9),
                                  f[0].substr(f[0].size() - 9)));
      }
      throw IoError(fmt::format("{}:{}: timestamp '{}' is not a number", path, in.line_number(), f[0]));
    }
    const auto v = parse_numbers(f, 1, path, in.line_number());
    check_finite(v, path, in.line_number());
    check_increasing(traj, pose.t, path, in.line_number());
    pose.p_WR = Eigen::Vector3d(v[0], v[1], v[2]);
    pose.q_WR = quat_wxyz(v[6], v[3], v[4], v[5], path, in.line_number());
    traj.poses.push_back(pose);
  }
  return traj;
}

Trajectory read_kitti(const std::string& path) {
  Trajectory traj;
  traj.source = path;
  traj.has_timestamps = false;
  LineReader in(path);
  std::string line;
  while (in.next(line)) {
    if (is_comment_or_blank(line)) continue;
    const auto f = split(line, ' ');
    if (f.size() != 12) {
      throw IoError(fmt::format("{}:{}: expected 12 numbers (3x4 [R|t]), found {}", path, in.line_number(), f.size()));
    }
    const auto v = parse_numbers(f, 0, path, in.line_number());
    check_finite(v, path, in.line_number(), 1);
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) R(r, c) = v[static_cast<size_t>(4 * r + c)];
      t[r] = v[static_cast<size_t>(4 * r + 3)];
    }
    const double err = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    if (!(err < 1e-3) || R.determinant() < 0.0) {
      throw DataError(fmt::format("{}:{}: rotation is not orthonormal (|R^T R - I| = {:.3g}, det = {:.6g})", path,
                                  in.line_number(), err, R.determinant()));
    }
    StampedPose pose;
    pose.t = static_cast<TimeNs>(traj.poses.size());
    pose.p_WR = t;
    // The nearest unit quaternion: R is orthonormal only to 1e-3, and Eigen's conversion keeps its scale.
    pose.q_WR = Eigen::Quaterniond(R).normalized();
    traj.poses.push_back(pose);
  }
  return traj;
}

/// Column layout of an EuRoC-style CSV.
struct CsvLayout {
  bool velocity = false;
  bool gyro_bias = false;
  bool accel_bias = false;
  bool covariance = false;
  size_t columns() const {
    return 8 + (velocity ? 3 : 0) + (gyro_bias ? 3 : 0) + (accel_bias ? 3 : 0) + (covariance ? 21 : 0);
  }
};

/// Layout from a header line's column names: group presence by name (v_/vx, b_w/bw, b_a/ba, cov_).
CsvLayout layout_from_header(const std::vector<std::string_view>& names) {
  CsvLayout l;
  for (auto name : names) {
    const std::string n = to_lower(name);
    if (n.rfind("v_", 0) == 0 || n == "vx") l.velocity = true;
    if (n.rfind("b_w", 0) == 0 || n == "bwx") l.gyro_bias = true;
    if (n.rfind("b_a", 0) == 0 || n == "bax") l.accel_bias = true;
    if (n.rfind("cov_", 0) == 0) l.covariance = true;
  }
  return l;
}

/// Layout from a column count alone (header-less files): 8 pose, 11 +v, 17 +v+biases, each optionally +21 cov.
bool layout_from_count(size_t n, CsvLayout& l) {
  l = CsvLayout{};
  if (n >= 29) {
    l.covariance = true;
    n -= 21;
  }
  if (n == 8) return true;
  if (n == 11) {
    l.velocity = true;
    return true;
  }
  if (n == 17) {
    l.velocity = l.gyro_bias = l.accel_bias = true;
    return true;
  }
  return false;
}

Trajectory read_euroc_csv(const std::string& path) {
  Trajectory traj;
  traj.source = path;
  LineReader in(path);
  std::string line;
  std::optional<CsvLayout> layout;
  while (in.next(line)) {
    const std::string_view s = trim(line);
    if (s.empty()) continue;
    if (s.front() == '#' || std::isalpha(static_cast<unsigned char>(s.front()))) {
      // A header names the columns when it has commas; a free comment line (e.g. "# rtslam ...") has fewer fields.
      const auto names = split(s.front() == '#' ? s.substr(1) : s, ',');
      if (!layout && names.size() >= 8) {
        layout = layout_from_header(names);
        if (layout->columns() != names.size()) {
          throw IoError(fmt::format("{}:{}: header has {} columns, which is not an EuRoC state layout", path,
                                    in.line_number(), names.size()));
        }
      }
      continue;
    }
    const auto f = split(s, ',');
    if (!layout) {
      CsvLayout l;
      if (!layout_from_count(f.size(), l)) {
        throw IoError(fmt::format("{}:{}: {} columns is not an EuRoC state layout (8, 11 or 17, +21 covariance)",
                                  path, in.line_number(), f.size()));
      }
      layout = l;
    }
    if (f.size() != layout->columns()) {
      throw IoError(fmt::format("{}:{}: expected {} columns, found {}", path, in.line_number(), layout->columns(),
                                f.size()));
    }
    StampedPose pose;
    if (!parse_int64(f[0], pose.t)) {
      throw IoError(fmt::format("{}:{}: timestamp '{}' is not an integer number of ns", path, in.line_number(), f[0]));
    }
    const auto v = parse_numbers(f, 1, path, in.line_number());
    check_finite(v, path, in.line_number());
    check_increasing(traj, pose.t, path, in.line_number());
    pose.p_WR = Eigen::Vector3d(v[0], v[1], v[2]);
    pose.q_WR = quat_wxyz(v[3], v[4], v[5], v[6], path, in.line_number());
    size_t k = 7;
    const auto vec3 = [&]() {
      Eigen::Vector3d x(v[k], v[k + 1], v[k + 2]);
      k += 3;
      return x;
    };
    if (layout->velocity) pose.v_WR = vec3();
    if (layout->gyro_bias) pose.gyro_bias = vec3();
    if (layout->accel_bias) pose.accel_bias = vec3();
    if (layout->covariance) {
      Eigen::Matrix<double, 6, 6> P;
      for (int r = 0; r < 6; ++r) {
        for (int c = r; c < 6; ++c) {
          P(r, c) = v[k++];
          P(c, r) = P(r, c);
        }
      }
      pose.cov = P;
    }
    traj.poses.push_back(pose);
  }
  return traj;
}

std::string first_data_line(const std::string& path) {
  LineReader in(path);
  std::string line;
  while (in.next(line)) {
    const std::string_view s = trim(line);
    if (s.empty() || s.front() == '#' || s.front() == '%') continue;
    if (std::isalpha(static_cast<unsigned char>(s.front()))) continue;  // a header without '#'
    return std::string(s);
  }
  return {};
}

void require_same_groups(const StampedPose& first, const StampedPose& p, size_t i, const std::string& path) {
  if (first.v_WR.has_value() != p.v_WR.has_value() || first.gyro_bias.has_value() != p.gyro_bias.has_value() ||
      first.accel_bias.has_value() != p.accel_bias.has_value() || first.cov.has_value() != p.cov.has_value()) {
    throw DataError(fmt::format("{}: pose {} has other optional fields (velocity/biases/covariance) than pose 0",
                                path, i));
  }
}

}  // namespace

TrajectoryFormat detect_trajectory_format(const std::string& path) {
  const std::string line = first_data_line(path);
  if (line.empty()) {
    // An empty trajectory: go by the extension.
    return to_lower(std::filesystem::path(path).extension().string()) == ".csv" ? TrajectoryFormat::EurocCsv
                                                                             : TrajectoryFormat::Tum;
  }
  if (line.find(',') != std::string::npos) return TrajectoryFormat::EurocCsv;
  const size_t n = split(line, ' ').size();
  if (n == 8) return TrajectoryFormat::Tum;
  if (n == 12) return TrajectoryFormat::Kitti;
  throw IoError(fmt::format("{}: cannot tell the trajectory format: first data line has {} space-separated fields "
                            "(TUM has 8, KITTI 12; EuRoC CSV uses commas)",
                            path, n));
}

Trajectory read_trajectory(const std::string& path, TrajectoryFormat format) {
  if (format == TrajectoryFormat::Auto) format = detect_trajectory_format(path);
  switch (format) {
    case TrajectoryFormat::Tum:
      return read_tum(path);
    case TrajectoryFormat::EurocCsv:
      return read_euroc_csv(path);
    case TrajectoryFormat::Kitti:
      return read_kitti(path);
    case TrajectoryFormat::Auto:
      break;
  }
  throw IoError(fmt::format("{}: unknown trajectory format", path));
}

void write_tum(const std::string& path, const Trajectory& trajectory) {
  AtomicFile file(path);
  std::ostream& out = file.stream();
  out << "# timestamp[s] tx ty tz qx qy qz qw\n";
  for (const auto& p : trajectory.poses) {
    const auto& q = p.q_WR;
    out << format_seconds(p.t) << ' ' << format_double(p.p_WR.x()) << ' ' << format_double(p.p_WR.y()) << ' '
        << format_double(p.p_WR.z()) << ' ' << format_double(q.x()) << ' ' << format_double(q.y()) << ' '
        << format_double(q.z()) << ' ' << format_double(q.w()) << '\n';
  }
  file.commit();
}

TrajectoryCsvWriter::TrajectoryCsvWriter(const std::string& path)
    : file_(path), last_flush_(std::chrono::steady_clock::now()) {}

void TrajectoryCsvWriter::write(const StampedPose& p) {
  std::ostream& out = file_.stream();
  if (!first_) {
    first_ = p;
    out << "# rtslam trajectory: pose T_WR of the robot frame R in the world W (p_RS_R = p_WR, q_RS = q_WR, Hamilton"
           " w x y z)";
    if (p.cov) {
      out << "; cov_ij = upper triangle (row-major) of the 6x6 covariance of [dp(3) dtheta(3)]: p = p_est + dp in W,"
             " q = q_est * Exp(dtheta) (right perturbation, dtheta in R)";
    }
    out << '\n';
    out << "#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []";
    if (p.v_WR) out << ", v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1]";
    if (p.gyro_bias) out << ", b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1]";
    if (p.accel_bias) out << ", b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]";
    if (p.cov) {
      for (int r = 0; r < 6; ++r)
        for (int c = r; c < 6; ++c) out << ", cov_" << r << c;
    }
    out << '\n';
  }
  require_same_groups(*first_, p, rows_, file_.path());
  ++rows_;
  row_ = fmt::format("{}", p.t);
  const auto put = [this](double x) {
    row_ += ',';
    row_ += format_double(x);
  };
  for (int k = 0; k < 3; ++k) put(p.p_WR[k]);
  put(p.q_WR.w());
  put(p.q_WR.x());
  put(p.q_WR.y());
  put(p.q_WR.z());
  if (p.v_WR)
    for (int k = 0; k < 3; ++k) put((*p.v_WR)[k]);
  if (p.gyro_bias)
    for (int k = 0; k < 3; ++k) put((*p.gyro_bias)[k]);
  if (p.accel_bias)
    for (int k = 0; k < 3; ++k) put((*p.accel_bias)[k]);
  if (p.cov)
    for (int r = 0; r < 6; ++r)
      for (int c = r; c < 6; ++c) put((*p.cov)(r, c));
  row_ += '\n';
  out << row_;
  const auto now = std::chrono::steady_clock::now();
  if (!out || now - last_flush_ >= std::chrono::seconds(1)) {
    last_flush_ = now;
    file_.flush();  // throws on a write error
  }
}

void TrajectoryCsvWriter::close() {
  if (file_.committed()) return;
  if (!first_) write_header_only();
  file_.commit();
}

void TrajectoryCsvWriter::write_header_only() {
  // No pose: the two header lines of a pose without optional groups.
  file_.stream() << "# rtslam trajectory: pose T_WR of the robot frame R in the world W (p_RS_R = p_WR, q_RS = q_WR, "
                    "Hamilton w x y z)\n#timestamp [ns], p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], "
                    "q_RS_x [], q_RS_y [], q_RS_z []\n";
}

void write_trajectory_csv(const std::string& path, const Trajectory& trajectory) {
  TrajectoryCsvWriter w(path);
  for (const auto& p : trajectory.poses) w.write(p);
  w.close();
}

void write_kitti(const std::string& path, const Trajectory& trajectory) {
  auto out = open_for_writing(path);
  for (const auto& p : trajectory.poses) {
    // Quaternions are kept as read (norm within 1e-2 of 1); the matrix of a non-unit one is not a rotation.
    const Eigen::Matrix3d R = p.q_WR.normalized().toRotationMatrix();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) out << format_double(R(r, c)) << ' ';
      out << format_double(p.p_WR[r]) << (r == 2 ? '\n' : ' ');
    }
  }
  close_checked(out, path);
}

}  // namespace rtslam::io
