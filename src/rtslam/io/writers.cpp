#include "rtslam/io/writers.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/io/text.hpp"

namespace rtslam::io {
namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------- atomic files

AtomicFile::AtomicFile(const std::string& path) : path_(path), tmp_(path + ".tmp") {
  out_.open(tmp_, std::ios::out | std::ios::trunc);
  if (!out_) throw IoError(fmt::format("{}: cannot open {} for writing", path_, tmp_));
}

AtomicFile::~AtomicFile() {
  if (!committed_) discard();
}

void AtomicFile::flush() {
  out_.flush();
  if (!out_) {
    // errno of the failed write (EFBIG, ENOSPC) is not kept by the stream: name the file, which is what users act on.
    const std::string msg = fmt::format("{}: write failed (disk full or file-size limit?)", path_);
    discard();
    throw IoError(msg);
  }
}

void AtomicFile::commit() {
  if (committed_) throw InvariantError(fmt::format("AtomicFile: {} committed twice", path_));
  flush();
  out_.close();
  if (out_.fail()) {
    discard();
    throw IoError(fmt::format("{}: write failed on close", path_));
  }
  std::error_code ec;
  fs::rename(tmp_, path_, ec);
  if (ec) {
    discard();
    throw IoError(fmt::format("{}: cannot rename {} to it: {}", path_, tmp_, ec.message()));
  }
  committed_ = true;
}

void AtomicFile::discard() noexcept {
  if (out_.is_open()) out_.close();
  std::error_code ec;
  fs::remove(tmp_, ec);
}

void write_atomically(const std::string& path, const std::function<void(std::ostream&)>& write) {
  AtomicFile f(path);
  write(f.stream());
  f.commit();
}

// ---------------------------------------------------------------------------------------------- map.ply

void write_map_ply(const std::string& path, const std::vector<MapPoint>& points) {
  const bool types = !points.empty() && std::all_of(points.begin(), points.end(), [](const MapPoint& p) {
    return p.euclidean.has_value();
  });
  AtomicFile file(path);
  std::ostream& out = file.stream();
  out << "ply\nformat ascii 1.0\ncomment rtslam map: landmark positions in W [m], per-axis and largest standard "
         "deviations [m], landmark id"
      << (types ? ", type (1 Euclidean, 0 anchored homogeneous)" : "") << "\n"
      << "element vertex " << points.size() << "\n"
      << "property double x\nproperty double y\nproperty double z\n"
      << "property double sigma_x\nproperty double sigma_y\nproperty double sigma_z\nproperty double sigma\n"
      << "property uint id\n"
      << (types ? "property uchar euclidean\n" : "") << "end_header\n";
  for (const auto& p : points) {
    const Eigen::Matrix3d sym = 0.5 * (p.cov + p.cov.transpose());
    const double largest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(sym, Eigen::EigenvaluesOnly).eigenvalues()(2);
    out << format_double(p.p_W.x()) << ' ' << format_double(p.p_W.y()) << ' ' << format_double(p.p_W.z());
    for (int k = 0; k < 3; ++k) out << ' ' << format_double(std::sqrt(std::max(0.0, sym(k, k))));
    out << ' ' << format_double(std::sqrt(std::max(0.0, largest))) << ' ' << p.id;
    if (types) out << ' ' << (*p.euclidean ? 1 : 0);
    out << '\n';
  }
  file.commit();
}

std::vector<MapPoint> read_map_ply(const std::string& path) {
  LineReader in(path);
  std::string line;
  std::size_t count = 0;
  bool header_done = false, types = false;
  while (!header_done && in.next(line)) {
    const auto f = split(line, ' ');
    if (in.line_number() == 1 && line != "ply") throw IoError(fmt::format("{}:1: not a PLY file", path));
    if (f.size() == 3 && f[0] == "element" && f[1] == "vertex") {
      std::int64_t n = 0;
      if (!parse_int64(f[2], n) || n < 0) throw IoError(fmt::format("{}:{}: bad vertex count", path, in.line_number()));
      count = static_cast<std::size_t>(n);
    }
    types = types || line == "property uchar euclidean";
    header_done = line == "end_header";
  }
  std::vector<MapPoint> points;
  const std::size_t fields = types ? 9 : 8;
  while (points.size() < count && in.next(line)) {
    const auto f = split(line, ' ');
    MapPoint p;
    double v[7];
    std::int64_t id = 0, euclidean = 0;
    bool ok = f.size() == fields && parse_int64(f[7], id) && (!types || parse_int64(f[8], euclidean));
    for (int k = 0; ok && k < 7; ++k) ok = parse_double(f[static_cast<size_t>(k)], v[k]);
    if (!ok) {
      throw IoError(fmt::format("{}:{}: expected 'x y z sigma_x sigma_y sigma_z sigma id{}'", path, in.line_number(),
                                types ? " euclidean" : ""));
    }
    p.p_W = Eigen::Vector3d(v[0], v[1], v[2]);
    p.cov = Eigen::Vector3d(v[3] * v[3], v[4] * v[4], v[5] * v[5]).asDiagonal();
    p.id = static_cast<std::uint64_t>(id);
    if (types) p.euclidean = euclidean != 0;
    points.push_back(p);
  }
  if (points.size() != count) {
    throw IoError(fmt::format("{}: header says {} vertices, found {}", path, count, points.size()));
  }
  return points;
}

// ---------------------------------------------------------------------------------------------- frames.csv

const char* FramesCsvWriter::header() {
  return "#timestamp [ns],camera,landmarks,predicted_visible,searched,matched,updated,initialized,ransac_inliers,"
         "t_predict [ms],t_match [ms],t_ransac [ms],t_update [ms],t_init [ms],t_map [ms],t_total [ms],"
         "refused,nis,nis_count,health,reset,budget_hit,budget_skipped,t_search [ms],absolute_updates,"
         "absolute_rejected,search_fallback,zero_velocity";
}

FramesCsvWriter::FramesCsvWriter(const std::string& path) : file_(path), last_flush_(std::chrono::steady_clock::now()) {
  file_.stream() << header() << '\n';
  file_.flush();
}

void FramesCsvWriter::write(const FrameStats& s) {
  std::ostream& out_ = file_.stream();
  out_ << s.t << ',' << s.camera << ',' << s.landmarks << ',' << s.predicted_visible << ',' << s.searched << ','
       << s.matched << ',' << s.updated << ',' << s.initialized << ',' << s.ransac_inliers << ','
       << format_double(s.t_predict_ms) << ',' << format_double(s.t_match_ms) << ',' << format_double(s.t_ransac_ms)
       << ',' << format_double(s.t_update_ms) << ',' << format_double(s.t_init_ms) << ',' << format_double(s.t_map_ms)
       << ',' << format_double(s.t_total_ms) << ',' << s.refused << ',' << format_double(s.nis) << ',' << s.nis_count
       << ',' << s.health << ',' << (s.reset ? 1 : 0) << ',' << (s.budget_hit ? 1 : 0) << ',' << s.budget_skipped << ','
       << format_double(s.t_search_ms) << ',' << s.absolute_updates << ',' << s.absolute_rejected << ','
       << s.search_fallback << ',' << (s.zero_velocity ? 1 : 0) << '\n';
  const auto now = std::chrono::steady_clock::now();
  if (!out_ || now - last_flush_ >= std::chrono::seconds(1)) {
    last_flush_ = now;
    file_.flush();  // throws on a write error
  }
}

void FramesCsvWriter::close() {
  if (!file_.committed()) file_.commit();
}

std::vector<FrameStats> read_frames_csv(const std::string& path) {
  LineReader in(path);
  std::string line;
  std::vector<FrameStats> rows;
  while (in.next(line)) {
    if (trim(line).empty() || trim(line).front() == '#') continue;
    const auto f = split(line, ',');
    FrameStats s;
    std::int64_t n[9];
    double ms[7];
    // 16 columns (files before the health columns), 21 (before the search budget's), 24 (before the absolute
    // sensors' counters), 26 (before the search fallback's), 27 (before the zero-velocity flag's) or 28.
    bool ok = f.size() == 16 || f.size() == 21 || f.size() == 24 || f.size() == 26 || f.size() == 27 ||
              f.size() == 28;
    for (size_t k = 0; ok && k < 9; ++k) ok = parse_int64(f[k], n[k]);
    for (size_t k = 0; ok && k < 7; ++k) ok = parse_double(f[9 + k], ms[k]);
    std::int64_t refused = 0, nis_count = 0, health = 0, reset = 0;
    double nis = 0.0;
    std::int64_t abs_updates = 0, abs_rejected = 0;
    if (ok && f.size() >= 21) {
      ok = parse_int64(f[16], refused) && parse_double(f[17], nis) && parse_int64(f[18], nis_count) &&
           parse_int64(f[19], health) && parse_int64(f[20], reset);
    }
    std::int64_t budget_hit = 0, budget_skipped = 0;
    double t_search = 0.0;
    if (ok && f.size() >= 24) {
      ok = parse_int64(f[21], budget_hit) && parse_int64(f[22], budget_skipped) && parse_double(f[23], t_search);
    }
    if (ok && f.size() >= 26) ok = parse_int64(f[24], abs_updates) && parse_int64(f[25], abs_rejected);
    std::int64_t fallback = 0;
    if (ok && f.size() >= 27) ok = parse_int64(f[26], fallback);
    std::int64_t zero_velocity = 0;
    if (ok && f.size() == 28) ok = parse_int64(f[27], zero_velocity);
    if (!ok) {
      throw IoError(fmt::format("{}:{}: expected 28 numeric columns ({}) or the first 27, 26, 24, 21 or 16 of them",
                                path, in.line_number(), FramesCsvWriter::header()));
    }
    s.t = n[0];
    int* counts[] = {&s.camera, &s.landmarks, &s.predicted_visible, &s.searched, &s.matched,
                     &s.updated, &s.initialized, &s.ransac_inliers};
    for (size_t k = 0; k < 8; ++k) *counts[k] = static_cast<int>(n[k + 1]);
    double* times[] = {&s.t_predict_ms, &s.t_match_ms, &s.t_ransac_ms, &s.t_update_ms,
                       &s.t_init_ms,    &s.t_map_ms,   &s.t_total_ms};
    for (size_t k = 0; k < 7; ++k) *times[k] = ms[k];
    s.refused = static_cast<int>(refused);
    s.nis = nis;
    s.nis_count = static_cast<int>(nis_count);
    s.health = static_cast<int>(health);
    s.reset = reset != 0;
    s.budget_hit = budget_hit != 0;
    s.budget_skipped = static_cast<int>(budget_skipped);
    s.t_search_ms = t_search;
    s.absolute_updates = static_cast<int>(abs_updates);
    s.absolute_rejected = static_cast<int>(abs_rejected);
    s.search_fallback = static_cast<int>(fallback);
    s.zero_velocity = zero_velocity != 0;
    rows.push_back(s);
  }
  // The writer starts every file with its header: a file without a line is truncated, not a run of no frame.
  if (in.line_number() == 0) throw IoError(fmt::format("{}: empty (not even the header line)", path));
  return rows;
}

// ---------------------------------------------------------------------------------------------- config / summary

void write_config_yaml(const std::string& path, const YAML::Node& config, const std::string& run_flags) {
  YAML::Emitter emitter;
  emitter.SetDoublePrecision(17);
  emitter << config;
  if (!emitter.good()) throw IoError(fmt::format("{}: cannot emit YAML: {}", path, emitter.GetLastError()));
  write_atomically(path, [&](std::ostream& out) {
    out << "# rtslam effective configuration: rerun with rtslam run " << (run_flags.empty() ? "" : run_flags + " ")
        << "--config " << path << "\n"
        << emitter.c_str() << '\n';
  });
}

void write_summary_json(const std::string& path, const nlohmann::json& summary) {
  write_atomically(path, [&](std::ostream& out) { out << summary.dump(2) << '\n'; });
}

Percentiles percentiles(std::vector<double> values) {
  Percentiles p;
  p.count = values.size();
  if (values.empty()) return p;
  std::sort(values.begin(), values.end());
  // Linear interpolation between closest ranks.
  const auto at = [&](double q) {
    const double pos = q * static_cast<double>(values.size() - 1);
    const auto lo = static_cast<std::size_t>(std::floor(pos));
    const std::size_t hi = std::min(lo + 1, values.size() - 1);
    return values[lo] + (pos - static_cast<double>(lo)) * (values[hi] - values[lo]);
  };
  p.median = at(0.5);
  p.p90 = at(0.9);
  p.p99 = at(0.99);
  p.max = values.back();
  p.mean = std::accumulate(values.begin(), values.end(), 0.0) / static_cast<double>(values.size());
  return p;
}

nlohmann::json to_json(const Percentiles& p) {
  return {{"count", p.count}, {"median", p.median}, {"p90", p.p90}, {"p99", p.p99}, {"max", p.max}, {"mean", p.mean}};
}

// ---------------------------------------------------------------------------------------------- EuRoC writer

namespace {

std::string euroc_distortion_name(DistortionModel m) {
  return m == DistortionModel::RadTan ? "radial-tangential" : to_string(m);
}

std::string t_bs_block(const Eigen::Isometry3d& T) {
  std::string s = "T_BS:\n  cols: 4\n  rows: 4\n  data: [";
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) s += (r || c ? ", " : "") + format_double(T.matrix()(r, c));
  return s + "]\n";
}

void make_dirs(const fs::path& p) {
  std::error_code ec;
  fs::create_directories(p, ec);
  if (ec) throw IoError(fmt::format("{}: cannot create folder: {}", p.string(), ec.message()));
}

void write_file(const fs::path& p, const std::string& text) {
  auto out = open_for_writing(p.string());
  out << text;
  close_checked(out, p.string());
}

}  // namespace

EurocWriter::EurocWriter(const std::string& root, const Rig& rig) : mav0_((fs::path(root) / "mav0").string()) {
  make_dirs(mav0_);
  for (std::size_t i = 0; i < rig.cameras.size(); ++i) {
    const auto& c = rig.cameras[i];
    const fs::path dir = fs::path(mav0_) / fmt::format("cam{}", i);
    make_dirs(dir / "data");
    std::string y = "%YAML:1.0\n# General sensor definitions.\nsensor_type: camera\ncomment: " + c.name +
                    " (written by rtslam)\n\n# Sensor extrinsics wrt. the body-frame.\n" + t_bs_block(c.T_RS) +
                    "\n# Camera specific definitions.\nrate_hz: " + format_double(c.rate_hz) + "\nresolution: [" +
                    std::to_string(c.width) + ", " + std::to_string(c.height) + "]\ncamera_model: pinhole\n" +
                    "intrinsics: [" + format_double(c.fx) + ", " + format_double(c.fy) + ", " + format_double(c.cx) +
                    ", " + format_double(c.cy) + "] #fu, fv, cu, cv\ndistortion_model: " +
                    euroc_distortion_name(c.distortion) + "\ndistortion_coefficients: [";
    for (std::size_t k = 0; k < c.distortion_coeffs.size(); ++k) y += (k ? ", " : "") + format_double(c.distortion_coeffs[k]);
    write_file(dir / "sensor.yaml", y + "]\n");
    cam_csv_path_.push_back((dir / "data.csv").string());
    cam_csv_.push_back(open_for_writing(cam_csv_path_.back()));
    cam_csv_.back() << "#timestamp [ns],filename\n";
  }
  if (rig.imu) {
    const auto& m = *rig.imu;
    const fs::path dir = fs::path(mav0_) / "imu0";
    make_dirs(dir);
    std::string y = "%YAML:1.0\n# General sensor definitions.\nsensor_type: imu\ncomment: " + m.name +
                    " (written by rtslam)\n\n# Sensor extrinsics wrt. the body-frame.\n" + t_bs_block(m.T_RS) +
                    "rate_hz: " + format_double(m.rate_hz) + "\n\n# inertial sensor noise model parameters (static)\n" +
                    "gyroscope_noise_density: " + format_double(m.gyro_noise_density) + "  # [ rad / s / sqrt(Hz) ]\n" +
                    "gyroscope_random_walk: " + format_double(m.gyro_random_walk) + "  # [ rad / s^2 / sqrt(Hz) ]\n" +
                    "accelerometer_noise_density: " + format_double(m.accel_noise_density) +
                    "  # [ m / s^2 / sqrt(Hz) ]\n" + "accelerometer_random_walk: " + format_double(m.accel_random_walk) +
                    "  # [ m / s^3 / sqrt(Hz) ]\n";
    if (m.gyro_saturation) y += "gyroscope_saturation: " + format_double(*m.gyro_saturation) + "  # [ rad / s ]\n";
    if (m.accel_saturation) y += "accelerometer_saturation: " + format_double(*m.accel_saturation) + "  # [ m / s^2 ]\n";
    write_file(dir / "sensor.yaml", y);
    imu_csv_path_ = (dir / "data.csv").string();
    imu_csv_ = open_for_writing(imu_csv_path_);
    imu_csv_ << "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],"
                "a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n";
  }
}

EurocWriter::~EurocWriter() {
  try {
    close();
  } catch (const Error& e) {
    logger("io")->error("{}", e.what());
  }
}

void EurocWriter::add_image(int camera, TimeNs t, const cv::Mat& image) {
  if (camera < 0 || static_cast<std::size_t>(camera) >= cam_csv_.size()) {
    throw InvariantError(fmt::format("EurocWriter: camera {} is not in the rig ({} cameras)", camera, cam_csv_.size()));
  }
  const std::string name = fmt::format("{}.png", t);
  const fs::path file = fs::path(mav0_) / fmt::format("cam{}", camera) / "data" / name;
  if (!codecs::imwrite(file.string(), image)) throw IoError(fmt::format("{}: cannot write the image", file.string()));
  auto& csv = cam_csv_[static_cast<std::size_t>(camera)];
  csv << t << ',' << name << '\n';
  if (!csv) throw IoError(fmt::format("{}: write failed", cam_csv_path_[static_cast<std::size_t>(camera)]));
}

void EurocWriter::add_imu(const ImuSample& s) {
  if (!imu_csv_.is_open()) throw InvariantError("EurocWriter: add_imu on a rig without an IMU");
  imu_csv_ << s.t;
  for (int k = 0; k < 3; ++k) imu_csv_ << ',' << format_double(s.gyro[k]);
  for (int k = 0; k < 3; ++k) imu_csv_ << ',' << format_double(s.accel[k]);
  imu_csv_ << '\n';
  if (!imu_csv_) throw IoError(fmt::format("{}: write failed", imu_csv_path_));
}

void EurocWriter::write_ground_truth(const Trajectory& trajectory) {
  const fs::path dir = fs::path(mav0_) / "state_groundtruth_estimate0";
  make_dirs(dir);
  write_file(dir / "sensor.yaml",
             "%YAML:1.0\n# General sensor definitions.\nsensor_type: visual-inertial\ncomment: ground truth "
             "(written by rtslam)\n\n# Sensor extrinsics wrt. the body-frame.\n" +
                 t_bs_block(Eigen::Isometry3d::Identity()));
  const std::string path = (dir / "data.csv").string();
  auto out = open_for_writing(path);
  const StampedPose first = trajectory.poses.empty() ? StampedPose{} : trajectory.poses.front();
  const bool full = first.v_WR && first.gyro_bias && first.accel_bias;
  out << "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z []";
  if (full) {
    out << ", v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], "
           "b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]";
  }
  out << '\n';
  for (std::size_t i = 0; i < trajectory.poses.size(); ++i) {
    const auto& p = trajectory.poses[i];
    const bool has = p.v_WR && p.gyro_bias && p.accel_bias;
    if (has != full) {
      throw DataError(fmt::format("{}: pose {} has other optional fields (velocity, biases) than pose 0", path, i));
    }
    out << p.t;
    for (int k = 0; k < 3; ++k) out << ',' << format_double(p.p_WR[k]);
    out << ',' << format_double(p.q_WR.w()) << ',' << format_double(p.q_WR.x()) << ',' << format_double(p.q_WR.y())
        << ',' << format_double(p.q_WR.z());
    if (full) {
      for (const Eigen::Vector3d* v : {&*p.v_WR, &*p.gyro_bias, &*p.accel_bias})
        for (int k = 0; k < 3; ++k) out << ',' << format_double((*v)[k]);
    }
    out << '\n';
  }
  close_checked(out, path);
}

void EurocWriter::close() {
  if (closed_) return;
  closed_ = true;
  for (std::size_t i = 0; i < cam_csv_.size(); ++i) close_checked(cam_csv_[i], cam_csv_path_[i]);
  if (imu_csv_.is_open()) close_checked(imu_csv_, imu_csv_path_);
}

// ---------------------------------------------------------------------------------------------- progress

ProgressLine::ProgressLine(std::size_t total, std::FILE* stream, std::optional<bool> enabled)
    : total_(total),
      stream_(stream ? stream : stderr),
      enabled_(enabled ? *enabled : ::isatty(::fileno(stream ? stream : stderr)) == 1),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {}

std::string ProgressLine::format(std::size_t done, std::size_t total, double elapsed_s) {
  const double rate = elapsed_s > 0 ? static_cast<double>(done) / elapsed_s : 0.0;
  std::string s = total > 0 ? fmt::format("frames {}/{} ({}%)", done, total, 100 * done / total)
                            : fmt::format("frames {}", done);
  s += fmt::format("  {:.1f} fps", rate);
  if (total > 0 && rate > 0 && done <= total) {
    const auto eta = static_cast<long long>(std::llround(static_cast<double>(total - done) / rate));
    s += fmt::format("  ETA {}:{:02d}", eta / 60, eta % 60);
  }
  return s;
}

void ProgressLine::update(std::size_t done) {
  done_ = done;
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (drawn_ && now - last_draw_ < std::chrono::milliseconds(250) && done != total_) return;
  last_draw_ = now;
  drawn_ = true;
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  std::fprintf(stream_, "\r%s\x1b[K", format(done, total_, elapsed).c_str());
  std::fflush(stream_);
}

void ProgressLine::finish() {
  if (!enabled_ || !drawn_) return;
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  std::fprintf(stream_, "\r%s\x1b[K\n", format(done_, total_, elapsed).c_str());
  std::fflush(stream_);
  drawn_ = false;
}

}  // namespace rtslam::io
