#include "rtslam/io/dataset.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <map>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/camera_source.hpp"
#include "rtslam/io/live_rig.hpp"
#include "rtslam/io/rosbag_source.hpp"
#include "rtslam/io/text.hpp"
#include "rtslam/io/trajectory_io.hpp"

namespace rtslam::io {
namespace fs = std::filesystem;
namespace {

// A dataset's ground truth, for the evaluation after the run only (nothing in the estimator reads it): a flawed file
// fails the open under the error policy; with --bad-input skip it is left out with a warning and the run goes on.
std::optional<Trajectory> read_ground_truth(const fs::path& path, TrajectoryFormat format, const DatasetOptions& o,
                                            Rig& rig) {
  try {
    return read_trajectory(path.string(), format);
  } catch (const Error& e) {
    if (o.bad_input != BadInputPolicy::Skip) throw;
    rig.warnings.push_back(fmt::format("ground truth not used (no accuracy figures): {}", e.what()));
    return std::nullopt;
  }
}

bool is_header(std::string_view s) {
  s = trim(s);
  return !s.empty() && (s.front() == '#' || std::isalpha(static_cast<unsigned char>(s.front())));
}

bool natural_less(const std::string& a, const std::string& b) {
  size_t i = 0;
  size_t j = 0;
  while (i < a.size() && j < b.size()) {
    if (std::isdigit(static_cast<unsigned char>(a[i])) && std::isdigit(static_cast<unsigned char>(b[j]))) {
      size_t i2 = i;
      size_t j2 = j;
      while (i2 < a.size() && std::isdigit(static_cast<unsigned char>(a[i2]))) ++i2;
      while (j2 < b.size() && std::isdigit(static_cast<unsigned char>(b[j2]))) ++j2;
      // Compare numerically: strip leading zeros, then by length, then lexicographically.
      size_t ia = i;
      size_t jb = j;
      while (ia + 1 < i2 && a[ia] == '0') ++ia;
      while (jb + 1 < j2 && b[jb] == '0') ++jb;
      if (i2 - ia != j2 - jb) return i2 - ia < j2 - jb;
      const int c = a.compare(ia, i2 - ia, b, jb, j2 - jb);
      if (c != 0) return c < 0;
      if (i2 - i != j2 - j) return i2 - i < j2 - j;
      i = i2;
      j = j2;
    } else {
      if (a[i] != b[j]) return a[i] < b[j];
      ++i;
      ++j;
    }
  }
  return a.size() - i < b.size() - j;
}

std::string first_existing(const fs::path& dir, std::initializer_list<const char*> names) {
  for (const char* n : names) {
    if (fs::is_regular_file(dir / n)) return (dir / n).string();
  }
  return {};
}

std::vector<cv::Size> sizes_of(const Rig& rig) {
  std::vector<cv::Size> sizes;
  for (const auto& c : rig.cameras) sizes.emplace_back(c.width, c.height);
  return sizes;
}

StreamCheckOptions check_options(const DatasetOptions& o, const Rig& rig) {
  StreamCheckOptions s;
  s.policy = o.bad_input;
  s.imu_rate_hz = rig.imu ? rig.imu->rate_hz : 0.0;
  s.max_imu_dropout = o.max_imu_dropout;
  if (rig.imu) s.imu_range = ImuRange::from_full_scale(rig.imu->gyro_saturation, rig.imu->accel_saturation);
  return s;
}

// ---------------------------------------------------------------------------------------------- EuRoC / ASL

/// Reads camN/data.csv (`t,filename`): entries with their line, malformed lines reported.
std::vector<ImageEntry> read_euroc_images(const fs::path& cam_dir, int camera, BadInputReporter& reporter) {
  const std::string csv = (cam_dir / "data.csv").string();
  LineReader in(csv);
  std::vector<ImageEntry> out;
  std::string line;
  while (in.next(line)) {
    if (trim(line).empty() || (in.line_number() == 1 && is_header(line)) || trim(line).front() == '#') continue;
    const auto f = split(line, ',');
    ImageEntry e;
    e.camera = camera;
    e.listed_at = fmt::format("{}:{}", csv, in.line_number());
    if (f.size() != 2 || f[1].empty() || !parse_int64(f[0], e.t)) {
      reporter.report(&SourceStats::malformed_lines,
                      fmt::format("{}: expected 'timestamp [ns],filename', got '{}'", e.listed_at, line), true);
      continue;
    }
    e.path = (cam_dir / "data" / std::string(f[1])).string();
    out.push_back(std::move(e));
  }
  if (out.empty()) throw DataError(fmt::format("{}: lists no image", csv));
  return out;
}

/// Reads imu0/data.csv (`t, w xyz, a xyz`).
void read_euroc_imu(const std::string& csv, std::vector<ImuSample>& imu, std::vector<int>& lines,
                    BadInputReporter& reporter) {
  LineReader in(csv);
  std::string line;
  while (in.next(line)) {
    if (trim(line).empty() || (in.line_number() == 1 && is_header(line)) || trim(line).front() == '#') continue;
    const auto f = split(line, ',');
    ImuSample s;
    bool ok = f.size() == 7 && parse_int64(f[0], s.t);
    for (int k = 0; ok && k < 3; ++k) ok = parse_double(f[1 + k], s.gyro[k]) && parse_double(f[4 + k], s.accel[k]);
    if (!ok) {
      reporter.report(&SourceStats::malformed_lines,
                      fmt::format("{}:{}: expected 7 numbers 'timestamp [ns], w_x, w_y, w_z, a_x, a_y, a_z', got '{}'",
                                  csv, in.line_number(), line),
                      true);
      continue;
    }
    imu.push_back(s);
    lines.push_back(in.line_number());
  }
}

Dataset open_euroc(const fs::path& root_in, const DatasetOptions& o) {
  const fs::path root = fs::is_directory(root_in / "mav0") ? root_in / "mav0" : root_in;
  Dataset ds;
  ds.kind = "euroc";
  ds.path = root_in.string();
  ds.name = (root.filename() == "mav0" ? root.parent_path() : root).filename().string();
  const fs::path imu_dir = root / "imu0";
  const bool has_imu = fs::is_regular_file(imu_dir / "data.csv");
  const bool has_imu_yaml = fs::is_regular_file(imu_dir / "sensor.yaml");
  for (int c : o.cameras) {
    const fs::path cam_dir = root / fmt::format("cam{}", c);
    if (!fs::is_directory(cam_dir)) throw IoError(fmt::format("{}: camera folder not found", cam_dir.string()));
  }
  if (o.calibration.empty()) {
    // The folder's own calibration, R the IMU (EuRoC's sensor.yaml files, or TUM-VI's dso/ Kalibr files). A run
    // without the IMU does not need its calibration: R is then the body frame (or the camchain's IMU).
    const FolderImu imu = !has_imu ? FolderImu::Skip : o.use_imu ? FolderImu::Required : FolderImu::IfPresent;
    ds.rig = load_euroc_folder_calibration(root.string(), o.cameras, imu);
  } else {
    const Rig all = load_calibration(o.calibration);
    ds.rig.imu = all.imu;
    ds.rig.t_d = all.t_d;
    ds.rig.warnings = all.warnings;
    if (!ds.rig.imu && has_imu && o.use_imu && !all.r_is_imu) {
      throw ConfigError(fmt::format("{}: no IMU, and its cameras are not given relative to one (no Kalibr T_cam_imu, "
                                    "no rig YAML imu block): an inertial run needs the camera–IMU extrinsics",
                                    o.calibration));
    }
    if (!ds.rig.imu && has_imu && o.use_imu && has_imu_yaml) {
      // An IMU–camera calibration without the IMU's noise (a Kalibr camchain: R is the IMU) completed by the folder's
      // IMU noise and rate; the IMU's own extrinsic is the camchain's business.
      ds.rig.imu = load_euroc_imu((imu_dir / "sensor.yaml").string());
      ds.rig.imu->T_RS = Eigen::Isometry3d::Identity();
      ds.rig.warnings.push_back(fmt::format("{} has no IMU: its noise densities and rate are taken from {}",
                                            o.calibration, (imu_dir / "sensor.yaml").string()));
    }
    for (int c : o.cameras) {
      if (c < 0 || static_cast<size_t>(c) >= all.cameras.size()) {
        throw ConfigError(fmt::format("{}: has no camera {}", o.calibration, c));
      }
      ds.rig.cameras.push_back(all.cameras[static_cast<size_t>(c)]);
    }
  }
  ds.rig.r_is_imu = ds.rig.imu.has_value();  // every path above that keeps an IMU puts R on it
  // Problems met while parsing the lists (malformed lines) follow the same policy; their counts are merged into
  // the source's stats.
  SourceStats scratch;
  const StreamCheckOptions checks = check_options(o, ds.rig);
  BadInputReporter parse_reporter(o.bad_input, scratch);
  std::vector<ImageEntry> images;
  for (size_t i = 0; i < o.cameras.size(); ++i) {
    auto e = read_euroc_images(root / fmt::format("cam{}", o.cameras[i]), static_cast<int>(i), parse_reporter);
    images.insert(images.end(), std::make_move_iterator(e.begin()), std::make_move_iterator(e.end()));
  }
  std::vector<ImuSample> imu;
  std::vector<int> lines;
  if (has_imu && o.use_imu) read_euroc_imu((imu_dir / "data.csv").string(), imu, lines, parse_reporter);
  auto src = std::make_unique<IndexedSource>(std::move(imu), std::move(lines), (imu_dir / "data.csv").string(),
                                             std::move(images), sizes_of(ds.rig), checks);
  src->add_parse_problems(scratch);
  ds.source = std::move(src);
  const std::string gt = euroc_ground_truth_file(root.string());
  if (!gt.empty()) ds.ground_truth = read_ground_truth(gt, TrajectoryFormat::EurocCsv, o, ds.rig);
  return ds;
}

// ---------------------------------------------------------------------------------------------- TUM

Rig calibration_for(const fs::path& dir, const DatasetOptions& o, std::initializer_list<const char*> names) {
  std::string path = o.calibration.empty() ? first_existing(dir, names) : o.calibration;
  if (path.empty()) {
    throw IoError(fmt::format("{}: no calibration file found (looked for {}): give one with the calibration option",
                              dir.string(), fmt::join(names, ", ")));
  }
  Rig rig = load_calibration(path);
  if (rig.cameras.empty()) throw ConfigError(fmt::format("{}: calibration has no camera", path));
  return rig;
}

Dataset open_tum(const fs::path& root, const DatasetOptions& o) {
  Dataset ds;
  ds.kind = "tum";
  ds.path = root.string();
  ds.name = root.filename().string();
  const Rig all = calibration_for(root, o, {"calibration.yaml", "camera.yaml", "sensor.yaml", "camchain.yaml"});
  ds.rig = all;
  ds.rig.cameras = {all.cameras.front()};
  ds.rig.imu.reset();  // TUM RGB-D accelerometer.txt is the Kinect's tilt sensor, not an IMU stream
  SourceStats scratch;
  BadInputReporter reporter(o.bad_input, scratch);
  const std::string list = (root / "rgb.txt").string();
  LineReader in(list);
  std::vector<ImageEntry> images;
  std::string line;
  while (in.next(line)) {
    const std::string_view s = trim(line);
    if (s.empty() || s.front() == '#') continue;
    const auto f = split(s, ' ');
    ImageEntry e;
    e.listed_at = fmt::format("{}:{}", list, in.line_number());
    if (f.size() != 2 || !parse_seconds(f[0], e.t)) {
      reporter.report(&SourceStats::malformed_lines,
                      fmt::format("{}: expected 'timestamp[s] filename', got '{}'", e.listed_at, line), true);
      continue;
    }
    e.path = (root / std::string(f[1])).string();
    images.push_back(std::move(e));
  }
  auto src = std::make_unique<IndexedSource>(std::vector<ImuSample>{}, std::vector<int>{}, "", std::move(images),
                                             sizes_of(ds.rig), check_options(o, ds.rig));
  src->add_parse_problems(scratch);
  ds.source = std::move(src);
  if (fs::is_regular_file(root / "groundtruth.txt")) {
    ds.ground_truth = read_ground_truth(root / "groundtruth.txt", TrajectoryFormat::Tum, o, ds.rig);
  }
  return ds;
}

// ---------------------------------------------------------------------------------------------- KITTI

std::vector<TimeNs> read_times(const std::string& path, BadInputReporter& reporter) {
  LineReader in(path);
  std::vector<TimeNs> times;
  std::string line;
  while (in.next(line)) {
    const std::string_view s = trim(line);
    if (s.empty() || s.front() == '#') continue;
    TimeNs t = 0;
    const auto f = split(s, ' ');
    if (f.empty() || !parse_seconds(f[0], t)) {
      reporter.report(&SourceStats::malformed_lines,
                      fmt::format("{}:{}: '{}' is not a time in seconds", path, in.line_number(), line), true);
      continue;
    }
    times.push_back(t);
  }
  return times;
}

Dataset open_kitti(const fs::path& seq, const DatasetOptions& o) {
  Dataset ds;
  ds.kind = "kitti";
  ds.path = seq.string();
  ds.name = "kitti-" + seq.filename().string();
  SourceStats scratch;
  BadInputReporter reporter(o.bad_input, scratch);
  const int cam_index = o.cameras.empty() ? 0 : o.cameras.front();
  if (o.cameras.size() > 1) throw ConfigError("kitti: only one camera (image_N folder) can be streamed");
  const fs::path image_dir = seq / fmt::format("image_{}", cam_index);
  const auto files = list_images(image_dir.string());
  if (files.empty()) throw IoError(fmt::format("{}: no images", image_dir.string()));
  const std::string times_path = (seq / "times.txt").string();
  const auto times = read_times(times_path, reporter);
  if (times.size() != files.size()) {
    throw DataError(fmt::format("{}: {} timestamps for {} images in {}", times_path, times.size(), files.size(),
                                image_dir.string()));
  }
  if (!o.calibration.empty()) {
    ds.rig = load_calibration(o.calibration);
    if (ds.rig.cameras.empty()) throw ConfigError(fmt::format("{}: calibration has no camera", o.calibration));
    ds.rig.cameras = {ds.rig.cameras.front()};
  } else {
    CameraCalibration cam = load_kitti_calib((seq / "calib.txt").string(), cam_index);
    std::string why;
    const cv::Mat first = read_grey_image(files.front(), &why);
    if (first.empty()) throw IoError(fmt::format("{}: {}", files.front(), why));
    cam.width = first.cols;
    cam.height = first.rows;
    check_camera_calibration(cam, fmt::format("{} ('P{}:' with the {}x{} px of {})", (seq / "calib.txt").string(),
                                              cam_index, cam.width, cam.height, files.front()));
    // The nominal rate over the sequence (0 = unknown: one time, times out of order, or a span beyond int64 ns;
    // the order itself is checked by the stream).
    TimeNs span = 0;
    const bool spans = times.size() > 1 && !__builtin_sub_overflow(times.back(), times.front(), &span) && span > 0;
    cam.rate_hz = spans ? (static_cast<double>(times.size()) - 1) / to_seconds(span) : 0.0;
    ds.rig.cameras.push_back(cam);
  }
  std::vector<ImageEntry> images;
  for (size_t i = 0; i < files.size(); ++i) {
    images.push_back({times[i], 0, files[i], fmt::format("{} (line {} of {})", files[i], i + 1, times_path)});
  }
  auto src = std::make_unique<IndexedSource>(std::vector<ImuSample>{}, std::vector<int>{}, "", std::move(images),
                                             sizes_of(ds.rig), check_options(o, ds.rig));
  src->add_parse_problems(scratch);
  ds.source = std::move(src);
  const fs::path poses = seq.parent_path().parent_path() / "poses" / (seq.filename().string() + ".txt");
  if (fs::is_regular_file(poses)) {
    ds.ground_truth = read_ground_truth(poses, TrajectoryFormat::Kitti, o, ds.rig);
  }
  if (ds.ground_truth) {
    Trajectory& gt = *ds.ground_truth;
    if (gt.poses.size() == times.size()) {
      for (size_t i = 0; i < times.size(); ++i) gt.poses[i].t = times[i];
      gt.has_timestamps = true;
    } else {
      logger("io")->warn("{}: {} poses for {} images: ground truth kept without timestamps", poses.string(),
                         gt.poses.size(), times.size());
    }
  }
  return ds;
}

// ---------------------------------------------------------------------------------------------- image folder

Dataset open_images(const fs::path& root, const DatasetOptions& o) {
  Dataset ds;
  ds.kind = "images";
  ds.path = root.string();
  ds.name = root.filename().string();
  const fs::path dir = fs::is_directory(root / "frames") ? root / "frames" : root;
  const Rig all =
      calibration_for(root, o, {"camera.json", "calibration.yaml", "camera.yaml", "sensor.yaml", "camchain.yaml"});
  ds.rig = all;
  ds.rig.cameras = {all.cameras.front()};
  ds.rig.imu.reset();
  const auto files = list_images(dir.string());
  if (files.empty()) throw IoError(fmt::format("{}: no image files", dir.string()));
  SourceStats scratch;
  BadInputReporter reporter(o.bad_input, scratch);
  std::vector<ImageEntry> images;
  const std::string ts = o.timestamps.empty() ? first_existing(root, {"times.txt", "timestamps.txt"}) : o.timestamps;
  // The images' own times win over a rate (a rate is for folders without them, docs/configuration.md; a preset may
  // carry one, as config/monoslam_davison.yaml does).
  if (!ts.empty() && o.rate_hz > 0) {
    ds.rig.warnings.push_back(fmt::format("{}: the rate {:g} Hz is not used: the images have their times in {}",
                                          root.string(), o.rate_hz, ts));
  }
  if (!ts.empty()) {
    // One time per line in seconds, for the images in sorted order; or `time filename` lines.
    LineReader in(ts);
    std::string line;
    size_t k = 0;
    bool by_index = true;
    int form = 0;  // entries per line of the first entry: 1 (time) or 2 (time filename)
    while (in.next(line)) {
      const std::string_view s = trim(line);
      if (s.empty() || s.front() == '#') continue;
      const auto f = split(s, ' ');
      ImageEntry e;
      e.listed_at = fmt::format("{}:{}", ts, in.line_number());
      if (f.empty() || f.size() > 2 || !parse_seconds(f[0], e.t)) {
        reporter.report(&SourceStats::malformed_lines,
                        fmt::format("{}: expected 'time[s]' or 'time[s] filename', got '{}'", e.listed_at, line), true);
        continue;
      }
      // One form per file: a `time filename` line among plain times (or the reverse) would make the index pairing
      // and the count check apply to neither, and images would be dropped silently.
      if (form != 0 && static_cast<std::size_t>(form) != f.size()) {
        throw DataError(fmt::format("{}: a '{}' line in a file whose first entry is a '{}' line: use one form",
                                    e.listed_at, f.size() == 2 ? "time filename" : "time",
                                    form == 2 ? "time filename" : "time"));
      }
      form = static_cast<int>(f.size());
      if (f.size() == 2) {
        by_index = false;
        e.path = (dir / std::string(f[1])).string();
      } else if (k < files.size()) {
        e.path = files[k];
      } else {
        throw DataError(fmt::format("{}: more timestamps than the {} images of {}", e.listed_at, files.size(),
                                    dir.string()));
      }
      ++k;
      images.push_back(std::move(e));
    }
    // With one time per line the times pair with the sorted images by index: the counts must agree, or images
    // would be dropped (or times invented) silently. With `time filename` lines the list chooses the images.
    if (by_index && k != files.size()) {
      throw DataError(fmt::format("{}: {} timestamps for {} images in {}", ts, k, files.size(), dir.string()));
    }
  } else {
    const double rate = o.rate_hz > 0 ? o.rate_hz : ds.rig.cameras.front().rate_hz;
    if (!(rate > 0)) {
      throw ConfigError(fmt::format("{}: no timestamps file and no rate: give the rate option", root.string()));
    }
    ds.rig.cameras.front().rate_hz = rate;
    for (size_t i = 0; i < files.size(); ++i) {
      const auto t = from_seconds_checked(static_cast<double>(i) / rate);
      if (!t) {
        throw ConfigError(fmt::format("{}: image {} at {:g} Hz lies beyond the int64 nanosecond time range (rate_hz "
                                      "must be in [{:g}, {:g}] Hz)",
                                      files[i], i, rate, DatasetOptions::kMinRateHz, DatasetOptions::kMaxRateHz));
      }
      images.push_back({*t, 0, files[i], files[i]});
    }
  }
  auto src = std::make_unique<IndexedSource>(std::vector<ImuSample>{}, std::vector<int>{}, "", std::move(images),
                                             sizes_of(ds.rig), check_options(o, ds.rig));
  src->add_parse_problems(scratch);
  ds.source = std::move(src);
  return ds;
}

// ---------------------------------------------------------------------------------------------- video

bool is_video_file(const fs::path& p) {
  static const char* kExt[] = {".mp4", ".avi", ".mkv", ".mov", ".webm", ".mpg", ".mpeg", ".m4v", ".wmv"};
  const std::string e = to_lower(p.extension().string());
  return std::any_of(std::begin(kExt), std::end(kExt), [&](const char* x) { return e == x; });
}

Dataset open_video(const fs::path& file, const DatasetOptions& o) {
  Dataset ds;
  ds.kind = "video";
  ds.path = file.string();
  ds.name = file.stem().string();
  const fs::path dir = file.parent_path().empty() ? fs::path(".") : file.parent_path();
  const Rig all = calibration_for(dir, o, {"camera.json", "calibration.yaml", "camera.yaml", "sensor.yaml",
                                           "camchain.yaml"});
  ds.rig = all;
  ds.rig.cameras = {all.cameras.front()};
  ds.rig.imu.reset();
  const auto& cam = ds.rig.cameras.front();
  auto src = std::make_unique<VideoSource>(file.string(), o.rate_hz, 0, cv::Size(cam.width, cam.height), o.bad_input);
  ds.rig.cameras.front().rate_hz = src->rate_hz();
  ds.source = std::move(src);
  return ds;
}

// ---------------------------------------------------------------------------------------------- camera (live)

Dataset open_camera(const std::string& spec, const DatasetOptions& o) {
  const CameraSpec cam = CameraSpec::parse(spec);
  if (o.calibration.empty()) {
    throw ConfigError(fmt::format("camera:{}: a live camera needs its calibration: give --calibration FILE (EuRoC "
                                  "sensor.yaml, Kalibr camchain.yaml, rtslam rig YAML or MonoSLAM camera.json)",
                                  spec));
  }
  if (o.cameras.size() != 1) {
    throw ConfigError(fmt::format("camera:{}: one camera per live input (slam/cameras lists {})", spec,
                                  o.cameras.size()));
  }
  Dataset ds;
  ds.kind = "camera";
  ds.path = cam.path;
  ds.name = cam.is_device ? fmt::format("video{}", cam.index) : fs::path(cam.path).stem().string();
  const Rig all = load_calibration(o.calibration);
  if (all.cameras.empty()) throw ConfigError(fmt::format("{}: calibration has no camera", o.calibration));
  ds.rig = all;
  ds.rig.cameras = {all.cameras.front()};
  const bool with_imu = o.use_imu && !o.imu_stream.empty();
  if (with_imu && !all.imu) {
    throw ConfigError(fmt::format("{}: no IMU in this calibration, which --imu-stream needs (the camera-IMU extrinsics "
                                  "and the IMU's noise: an rtslam rig YAML with an imu block, or a Kalibr camchain "
                                  "with its imu.yaml; docs/datasets.md)",
                                  o.calibration));
  }
  if (!with_imu) ds.rig.imu.reset();  // no live IMU is read (docs/datasets.md "Live camera")
  const auto& c = ds.rig.cameras.front();
  // A device is asked for the calibration's rate unless --rate says otherwise; a file standing in for one keeps its
  // own frame times (as video:FILE does) unless --rate is given.
  const double rate_hz = o.rate_hz > 0.0 ? o.rate_hz : (cam.is_device ? c.rate_hz : 0.0);
  auto src = std::make_unique<CameraSource>(cam, cv::Size(c.width, c.height), rate_hz, o.bad_input);
  ds.rig.cameras.front().rate_hz = src->rate_hz();
  if (!with_imu) {
    ds.source = std::move(src);
    return ds;
  }
  ImuStreamReader::Options ro;
  ro.clock = o.imu_clock;
  ro.range = ImuRange::from_full_scale(ds.rig.imu->gyro_saturation, ds.rig.imu->accel_saturation);
  ro.rate_hz = ds.rig.imu->rate_hz;
  ro.max_dropout = o.max_imu_dropout;
  auto imu = std::make_unique<ImuStreamReader>(o.imu_stream, ro);
  LiveSource::Options lo;
  lo.policy = o.bad_input;
  // --stop-after ends the run by the times of what it processes (WindowSource, below), and nothing is processed
  // before the IMU's first sample: the live source ends a run whose IMU never delivers after that much input.
  if (o.duration_s > 0.0) lo.end_without_imu_after_s = o.start_offset_s + o.duration_s;
  ds.source = std::make_unique<LiveRigSource>(std::move(src), std::move(imu), lo);
  return ds;
}

}  // namespace

std::vector<std::string> list_images(const std::string& folder) {
  static const char* kExt[] = {".png", ".pgm", ".ppm", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff"};
  if (!fs::is_directory(folder)) throw IoError(fmt::format("{}: folder not found", folder));
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(folder)) {
    if (!entry.is_regular_file()) continue;
    const std::string e = to_lower(entry.path().extension().string());
    if (std::any_of(std::begin(kExt), std::end(kExt), [&](const char* x) { return e == x; })) {
      names.push_back(entry.path().filename().string());
    }
  }
  std::sort(names.begin(), names.end(), natural_less);
  for (auto& n : names) n = (fs::path(folder) / n).string();
  return names;
}

std::string euroc_ground_truth_file(const std::string& mav0) {
  for (const char* name : {"state_groundtruth_estimate0", "mocap0"}) {
    const fs::path file = fs::path(mav0) / name / "data.csv";
    if (fs::is_regular_file(file)) return file.string();
  }
  return {};
}

std::string detect_dataset_kind(const std::string& path) {
  const fs::path p(path);
  if (fs::is_regular_file(p)) {
    if (is_video_file(p)) return "video";
    if (to_lower(p.extension().string()) == ".bag") return "rosbag";
    throw IoError(fmt::format("{}: a file that is not a known video type (mp4, avi, mkv, ...) or a ROS bag (.bag)",
                              path));
  }
  if (!fs::is_directory(p)) throw IoError(fmt::format("{}: dataset not found", path));
  if (fs::is_directory(p / "mav0") || fs::is_regular_file(p / "imu0" / "data.csv") ||
      fs::is_regular_file(p / "cam0" / "data.csv")) {
    return "euroc";
  }
  if (fs::is_regular_file(p / "rgb.txt")) return "tum";
  if (fs::is_directory(p / "image_0") && fs::is_regular_file(p / "times.txt")) return "kitti";
  if (!list_images(fs::is_directory(p / "frames") ? (p / "frames").string() : path).empty()) return "images";
  throw IoError(fmt::format("{}: cannot tell the dataset kind (no mav0/, rgb.txt, image_0/ + times.txt, or images)",
                            path));
}

namespace {
// The rig's warnings logged, and the start offset / duration window applied.
Dataset with_window(Dataset ds, const std::string& spec, const DatasetOptions& options) {
  for (const auto& w : ds.rig.warnings) logger("io")->warn("{}", w);
  if (options.start_offset_s != 0.0 || options.duration_s != 0.0) {
    if (!(options.start_offset_s >= 0.0) || !(options.duration_s >= 0.0)) {
      throw ConfigError(fmt::format("dataset '{}': start offset {} s and duration {} s must be >= 0", spec,
                                    options.start_offset_s, options.duration_s));
    }
    ds.source = std::make_unique<WindowSource>(std::move(ds.source), options.start_offset_s, options.duration_s);
  }
  return ds;
}
}  // namespace

void DatasetOptions::validate() const {
  const std::string w = "dataset options";
  require_bound(rate_hz == 0.0 || (rate_hz >= kMinRateHz && rate_hz <= kMaxRateHz), w, "rate_hz (--rate)", rate_hz,
                fmt::format("0 (from the data) or in [{:g}, {:g}] Hz", kMinRateHz, kMaxRateHz));
  require_bound(max_imu_dropout >= 0 && max_imu_dropout <= kMaxImuDropout, w, "max_imu_dropout (--max-imu-dropout)",
                max_imu_dropout, fmt::format("in [0, {}] samples", kMaxImuDropout));
  require_bound(start_offset_s >= 0.0 && start_offset_s <= kMaxTimeSeconds, w, "start_offset_s (--start-at)",
                start_offset_s, fmt::format("in [0, {:g}] s", kMaxTimeSeconds));
  require_bound(duration_s >= 0.0 && duration_s <= kMaxTimeSeconds, w, "duration_s (--stop-after)", duration_s,
                fmt::format("in [0, {:g}] s", kMaxTimeSeconds));
  for (const int c : cameras) {
    require_bound(c >= 0 && c <= kMaxCameraIndex, w, "cameras[]", c, fmt::format("in [0, {}]", kMaxCameraIndex));
  }
}

Dataset open_dataset(const std::string& spec, const DatasetOptions& options) {
  options.validate();
  std::string kind;
  std::string path = spec;
  const size_t colon = spec.find(':');
  if (colon != std::string::npos && colon > 1) {  // "euroc:/data/..." (colon > 1 keeps "C:\\..." paths intact)
    const std::string k = to_lower(spec.substr(0, colon));
    if (k == "euroc" || k == "asl" || k == "tum" || k == "kitti" || k == "images" || k == "video" || k == "rosbag" ||
        k == "camera") {
      kind = k == "asl" ? "euroc" : k;
      path = spec.substr(colon + 1);
    } else if (!fs::exists(spec)) {
      throw ConfigError(fmt::format(
          "dataset '{}': unknown kind '{}' (known: euroc, tum, kitti, images, video, rosbag, camera)", spec, k));
    }
  }
  if (kind.empty()) kind = detect_dataset_kind(path);
  if (!options.imu_stream.empty() && kind != "camera") {
    throw ConfigError(fmt::format("dataset '{}': --imu-stream pairs a live IMU with a camera:N input only (a {} "
                                  "dataset brings its own IMU data)",
                                  spec, kind));
  }
  Dataset ds;
  if (kind == "camera") {
    ds = open_camera(path, options);
    return with_window(std::move(ds), spec, options);
  }
  if (!fs::exists(path)) throw IoError(fmt::format("{}: dataset not found", path));
  const fs::path p = fs::path(path).lexically_normal();
  const fs::path root = p.has_filename() ? p : p.parent_path();
  if (kind == "euroc") {
    ds = open_euroc(root, options);
  } else if (kind == "tum") {
    ds = open_tum(root, options);
  } else if (kind == "kitti") {
    ds = open_kitti(root, options);
  } else if (kind == "images") {
    ds = open_images(root, options);
  } else if (kind == "rosbag") {
    ds = open_rosbag(root.string(), options);
  } else {
    ds = open_video(root, options);
  }
  return with_window(std::move(ds), spec, options);
}

}  // namespace rtslam::io
