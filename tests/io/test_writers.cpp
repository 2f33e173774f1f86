#include "rtslam/io/writers.hpp"

#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "io_test_util.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/text.hpp"
#include "rtslam/io/trajectory_io.hpp"

namespace rtslam::io {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

bool bits_equal(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

bool bits_equal(const Eigen::Ref<const Eigen::MatrixXd>& a, const Eigen::Ref<const Eigen::MatrixXd>& b) {
  if (a.rows() != b.rows() || a.cols() != b.cols()) return false;
  for (Eigen::Index i = 0; i < a.size(); ++i)
    if (!bits_equal(a.data()[i], b.data()[i])) return false;
  return true;
}

Rig random_rig(Rng& rng) {
  Rig rig;
  for (int i = 0; i < 2; ++i) {
    CameraCalibration c;
    c.name = "cam" + std::to_string(i);
    c.width = 32;
    c.height = 24;
    c.rate_hz = 20;
    c.fx = 30 + randu(rng, 0, 1);
    c.fy = 30 + randu(rng, 0, 1);
    c.cx = 16 + randn(rng) * 0.1;
    c.cy = 12 + randn(rng) * 0.1;
    c.distortion = i == 0 ? DistortionModel::RadTan : DistortionModel::Equidistant;
    c.distortion_coeffs = {randn(rng) * 0.1, randn(rng) * 0.01, randn(rng) * 1e-3, randn(rng) * 1e-4};
    c.T_RS = Eigen::Translation3d(randn_vec<3>(rng, 0.05)) *
             Eigen::Quaterniond(Eigen::Vector4d(randn_vec<4>(rng))).normalized();
    rig.cameras.push_back(c);
  }
  ImuCalibration imu;
  imu.rate_hz = 200;
  imu.gyro_noise_density = 1.6968e-04;
  imu.gyro_random_walk = 1.9393e-05;
  imu.accel_noise_density = 2.0e-3;
  imu.accel_random_walk = 3.0e-3;
  imu.gyro_saturation = 5.235987755982989;
  rig.imu = imu;
  return rig;
}

TEST(EurocWriter, WhatItWritesTheReaderReadsBackBitIdentically) {
  TempDir dir;
  Rng rng(2024);
  const Rig rig = random_rig(rng);
  std::vector<ImuSample> imu;
  std::vector<std::pair<TimeNs, cv::Mat>> images;
  Trajectory gt;
  const TimeNs t0 = 1403715273262142976;
  {
    EurocWriter w(dir / "seq", rig);
    for (int i = 0; i < 200; ++i) {
      ImuSample s;
      s.t = t0 + i * 5'000'000;
      s.gyro = randn_vec<3>(rng, 0.1);
      s.accel = randn_vec<3>(rng, 9.81);
      imu.push_back(s);
      w.add_imu(s);
      if (i % 10 == 0) {
        cv::Mat img(24, 32, CV_8UC1);
        cv::RNG cvrng(static_cast<uint64_t>(i) + 1);
        cvrng.fill(img, cv::RNG::UNIFORM, 0, 256);
        for (int c = 0; c < 2; ++c) w.add_image(c, s.t, img);
        images.emplace_back(s.t, img.clone());
        StampedPose p;
        p.t = s.t;
        p.p_WR = randn_vec<3>(rng);
        p.q_WR = Eigen::Quaterniond(Eigen::Vector4d(randn_vec<4>(rng))).normalized();
        p.v_WR = randn_vec<3>(rng);
        p.gyro_bias = randn_vec<3>(rng, 1e-3);
        p.accel_bias = randn_vec<3>(rng, 1e-2);
        gt.poses.push_back(p);
      }
    }
    w.write_ground_truth(gt);
    w.close();
  }
  // Standard layout and headers.
  EXPECT_TRUE(fs::is_regular_file(dir / "seq/mav0/cam1/sensor.yaml"));
  EXPECT_EQ(test::read_text(dir / "seq/mav0/imu0/data.csv").rfind("#timestamp [ns],w_RS_S_x [rad s^-1]", 0), 0u);
  EXPECT_EQ(test::read_text(dir / "seq/mav0/cam0/data.csv").rfind("#timestamp [ns],filename\n", 0), 0u);
  EXPECT_EQ(test::read_text(dir / "seq/mav0/cam0/sensor.yaml").rfind("%YAML:1.0\n", 0), 0u);

  DatasetOptions o;
  o.cameras = {0, 1};
  Dataset ds = open_dataset(dir / "seq", o);
  EXPECT_EQ(ds.kind, "euroc");
  ASSERT_EQ(ds.rig.cameras.size(), 2u);
  for (size_t c = 0; c < 2; ++c) {
    const auto& a = rig.cameras[c];
    const auto& b = ds.rig.cameras[c];
    EXPECT_EQ(b.width, a.width);
    EXPECT_TRUE(bits_equal(b.fx, a.fx) && bits_equal(b.fy, a.fy) && bits_equal(b.cx, a.cx) && bits_equal(b.cy, a.cy));
    EXPECT_EQ(b.distortion, a.distortion);
    ASSERT_EQ(b.distortion_coeffs.size(), 4u);
    for (size_t k = 0; k < 4; ++k) EXPECT_TRUE(bits_equal(b.distortion_coeffs[k], a.distortion_coeffs[k]));
    EXPECT_TRUE(bits_equal(b.T_RS.matrix(), a.T_RS.matrix())) << b.T_RS.matrix() << "\n" << a.T_RS.matrix();
  }
  ASSERT_TRUE(ds.rig.imu.has_value());
  EXPECT_TRUE(bits_equal(ds.rig.imu->gyro_random_walk, rig.imu->gyro_random_walk));
  EXPECT_TRUE(bits_equal(*ds.rig.imu->gyro_saturation, *rig.imu->gyro_saturation));
  size_t n_imu = 0;
  size_t n_img = 0;
  while (auto m = ds.source->next()) {
    if (auto* s = std::get_if<ImuSample>(&*m)) {
      ASSERT_LT(n_imu, imu.size());
      EXPECT_EQ(s->t, imu[n_imu].t);
      EXPECT_TRUE(bits_equal(s->gyro, imu[n_imu].gyro) && bits_equal(s->accel, imu[n_imu].accel)) << n_imu;
      ++n_imu;
    } else {
      const auto& f = std::get<ImageFrame>(*m);
      const auto& expected = images[n_img / 2];
      EXPECT_EQ(f.t, expected.first);
      EXPECT_EQ(f.camera, static_cast<int>(n_img % 2));
      EXPECT_EQ(cv::norm(f.image, expected.second, cv::NORM_INF), 0.0);
      ++n_img;
    }
  }
  EXPECT_EQ(n_imu, 200u);
  EXPECT_EQ(n_img, 40u);
  ASSERT_TRUE(ds.ground_truth.has_value());
  ASSERT_EQ(ds.ground_truth->poses.size(), gt.poses.size());
  for (size_t i = 0; i < gt.poses.size(); ++i) {
    const auto& a = gt.poses[i];
    const auto& b = ds.ground_truth->poses[i];
    EXPECT_EQ(a.t, b.t);
    EXPECT_TRUE(bits_equal(a.p_WR, b.p_WR) && bits_equal(a.q_WR.coeffs(), b.q_WR.coeffs()));
    EXPECT_TRUE(bits_equal(*a.v_WR, *b.v_WR) && bits_equal(*a.gyro_bias, *b.gyro_bias) &&
                bits_equal(*a.accel_bias, *b.accel_bias));
  }
}

TEST(MapPly, WritesTheLandmarkTypesWhenEveryOneIsKnown) {
  TempDir dir;
  std::vector<MapPoint> pts(2);
  pts[0].id = 4;
  pts[0].euclidean = true;
  pts[1].id = 9;
  pts[1].euclidean = false;
  write_map_ply(dir / "typed.ply", pts);
  const std::string text = test::read_text(dir / "typed.ply");
  EXPECT_NE(text.find("property uint id\nproperty uchar euclidean\nend_header\n"), std::string::npos) << text;
  const auto back = read_map_ply(dir / "typed.ply");
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[0].euclidean, std::optional<bool>(true));
  EXPECT_EQ(back[1].euclidean, std::optional<bool>(false));
  // One point of unknown type: no such property (a PLY property is every vertex's), read back as unknown.
  pts[1].euclidean.reset();
  write_map_ply(dir / "untyped.ply", pts);
  EXPECT_EQ(test::read_text(dir / "untyped.ply").find("euclidean"), std::string::npos);
  EXPECT_FALSE(read_map_ply(dir / "untyped.ply")[0].euclidean.has_value());
}

TEST(MapPly, WritesAsciiPlyWithSigmasAndIds) {
  TempDir dir;
  std::vector<MapPoint> pts(3);
  for (size_t i = 0; i < pts.size(); ++i) {
    pts[i].id = 100 + i;
    pts[i].p_W = Eigen::Vector3d(0.1 * static_cast<double>(i), -1.0, 2.5);
    pts[i].cov = Eigen::Vector3d(0.01, 0.04, 0.09 * static_cast<double>(i + 1)).asDiagonal();
  }
  pts[1].cov(0, 1) = pts[1].cov(1, 0) = 0.015;
  pts[1].cov(2, 2) = 0.001;
  write_map_ply(dir / "map.ply", pts);
  const std::string text = test::read_text(dir / "map.ply");
  EXPECT_EQ(text.rfind("ply\nformat ascii 1.0\n", 0), 0u);
  EXPECT_NE(text.find("element vertex 3\n"), std::string::npos);
  EXPECT_NE(text.find("property uint id\nend_header\n"), std::string::npos);
  const auto back = read_map_ply(dir / "map.ply");
  ASSERT_EQ(back.size(), 3u);
  EXPECT_EQ(back[2].id, 102u);
  EXPECT_EQ(back[1].p_W, pts[1].p_W);
  EXPECT_NEAR(back[2].cov(2, 2), 0.27, 1e-15);
  // The `sigma` column is the largest std dev: for [[0.01, 0.015], [0.015, 0.04]] it is above the diagonal's 0.2.
  const std::string body = text.substr(text.find("end_header\n") + 11);
  const auto lines = split(body, '\n');
  const auto f = split(lines[1], ' ');
  double sigma = 0;
  ASSERT_TRUE(parse_double(f[6], sigma));
  const double lmax = 0.025 + std::sqrt(0.015 * 0.015 + 0.015 * 0.015);
  EXPECT_NEAR(sigma, std::sqrt(lmax), 1e-12);
}

TEST(FramesCsv, RoundTripsEveryField) {
  TempDir dir;
  std::vector<FrameStats> rows(5);
  for (size_t i = 0; i < rows.size(); ++i) {
    auto& s = rows[i];
    s.t = 1403715273262142976 + static_cast<TimeNs>(i) * 50'000'000;
    s.landmarks = 40 + static_cast<int>(i);
    s.predicted_visible = 20;
    s.searched = 18;
    s.matched = 15;
    s.updated = 12;
    s.initialized = static_cast<int>(i % 2);
    s.ransac_inliers = 11;
    s.t_predict_ms = 0.1 * static_cast<double>(i);
    s.t_total_ms = 3.0 + 1.0 / 3.0;
    s.refused = static_cast<int>(i % 3);
    s.nis = 17.25 + static_cast<double>(i);
    s.nis_count = 9;
    s.health = static_cast<int>(i % 3);
    s.reset = i == 2;
    s.budget_hit = i == 3;
    s.budget_skipped = static_cast<int>(2 * i);
    s.t_search_ms = 0.25 + 1.0 / 7.0 * static_cast<double>(i);
    s.absolute_updates = 5 + static_cast<int>(i);
    s.absolute_rejected = static_cast<int>(i % 2);
    s.search_fallback = static_cast<int>(i % 4);
    s.zero_velocity = i % 2 == 1;
  }
  {
    FramesCsvWriter w(dir / "frames.csv");
    for (const auto& r : rows) w.write(r);
    EXPECT_FALSE(fs::exists(dir / "frames.csv")) << "streamed into frames.csv.tmp until close()";
    EXPECT_TRUE(fs::exists(dir / "frames.csv.tmp"));
    w.close();
  }
  EXPECT_FALSE(fs::exists(dir / "frames.csv.tmp"));
  const auto back = read_frames_csv(dir / "frames.csv");
  ASSERT_EQ(back.size(), rows.size());
  {  // Review 27 Nov: an empty file read as a run of no frame (rtslam view showed nothing, exit 0).
    std::ofstream empty(dir / "empty.csv");
  }
  EXPECT_THROW(read_frames_csv(dir / "empty.csv"), IoError);
  {
    FramesCsvWriter none(dir / "none.csv");
    none.close();
  }
  EXPECT_TRUE(read_frames_csv(dir / "none.csv").empty());  // the header alone: a run that processed no frame
  for (size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(back[i].t, rows[i].t);
    EXPECT_EQ(back[i].landmarks, rows[i].landmarks);
    EXPECT_EQ(back[i].initialized, rows[i].initialized);
    EXPECT_EQ(back[i].ransac_inliers, rows[i].ransac_inliers);
    EXPECT_EQ(back[i].t_predict_ms, rows[i].t_predict_ms);
    EXPECT_EQ(back[i].t_total_ms, rows[i].t_total_ms);
    EXPECT_EQ(back[i].refused, rows[i].refused);
    EXPECT_EQ(back[i].nis, rows[i].nis);
    EXPECT_EQ(back[i].nis_count, rows[i].nis_count);
    EXPECT_EQ(back[i].health, rows[i].health);
    EXPECT_EQ(back[i].reset, rows[i].reset);
    EXPECT_EQ(back[i].budget_hit, rows[i].budget_hit);
    EXPECT_EQ(back[i].budget_skipped, rows[i].budget_skipped);
    EXPECT_EQ(back[i].t_search_ms, rows[i].t_search_ms);
    EXPECT_EQ(back[i].absolute_updates, rows[i].absolute_updates);
    EXPECT_EQ(back[i].absolute_rejected, rows[i].absolute_rejected);
    EXPECT_EQ(back[i].search_fallback, rows[i].search_fallback);
    EXPECT_EQ(back[i].zero_velocity, rows[i].zero_velocity);
  }
  EXPECT_EQ(test::read_text(dir / "frames.csv").rfind(FramesCsvWriter::header(), 0), 0u);
}

TEST(AtomicFile, CommitRenamesTheTmpAndAnExceptionKeepsThePreviousFile) {
  TempDir dir;
  const std::string path = dir / "summary.json";
  write_atomically(path, [](std::ostream& out) { out << "old\n"; });
  EXPECT_EQ(test::read_text(dir / "summary.json"), "old\n");
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  // A writer that throws half-way: the final name keeps the previous file, the .tmp is gone.
  EXPECT_THROW(write_atomically(path,
                                [](std::ostream& out) {
                                  out << "half";
                                  throw DataError("bad pose");
                                }),
               DataError);
  EXPECT_EQ(test::read_text(dir / "summary.json"), "old\n");
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  {
    AtomicFile f(path);
    f.stream() << "new\n";
    f.flush();
    EXPECT_EQ(test::read_text(path + ".tmp"), "new\n") << "flushed data is in the .tmp";
    f.commit();
  }
  EXPECT_EQ(test::read_text(dir / "summary.json"), "new\n");
  EXPECT_THROW(AtomicFile(dir / "absent/x.csv"), IoError);
}

TEST(FramesCsv, WithoutCloseNoFileIsLeft) {
  TempDir dir;
  {
    FramesCsvWriter w(dir / "frames.csv");
    w.write(FrameStats{});
  }
  EXPECT_FALSE(fs::exists(dir / "frames.csv"));
  EXPECT_FALSE(fs::exists(dir / "frames.csv.tmp"));
}

// Files of earlier versions (fewer columns) still read: the columns they lack read as 0; any other count is refused.
TEST(FramesCsv, ReadsTheShorterRowsOfEarlierVersions) {
  TempDir dir;
  FrameStats s;
  s.t = 1000;
  s.landmarks = 7;
  s.t_total_ms = 2.5;
  s.absolute_updates = 3;
  s.absolute_rejected = 1;
  s.search_fallback = 2;
  s.zero_velocity = true;
  {
    FramesCsvWriter w(dir / "frames.csv");
    w.write(s);
    w.close();
  }
  const std::string row = test::read_text(dir / "frames.csv").substr(std::string(FramesCsvWriter::header()).size() + 1);
  std::vector<std::string> fields;
  for (std::size_t a = 0, b; a <= row.size(); a = b + 1) {
    b = row.find_first_of(",\n", a);
    if (b == std::string::npos) b = row.size();
    if (b > a) fields.push_back(row.substr(a, b - a));
  }
  ASSERT_EQ(fields.size(), 28u);
  for (const std::size_t columns : {27u, 26u, 24u, 21u, 16u, 25u}) {
    std::string text = "#header\n";
    for (std::size_t k = 0; k < columns; ++k) text += (k > 0 ? "," : "") + fields[k];
    test::write_text(dir / "old.csv", text + "\n");
    if (columns == 25) {
      EXPECT_THROW(read_frames_csv(dir / "old.csv"), IoError);
      continue;
    }
    const auto back = read_frames_csv(dir / "old.csv");
    ASSERT_EQ(back.size(), 1u) << columns;
    EXPECT_EQ(back[0].t, 1000);
    EXPECT_EQ(back[0].landmarks, 7);
    EXPECT_EQ(back[0].t_total_ms, 2.5);
    EXPECT_EQ(back[0].absolute_updates, columns >= 26 ? 3 : 0) << columns;
    EXPECT_EQ(back[0].search_fallback, columns >= 27 ? 2 : 0) << columns;
    EXPECT_FALSE(back[0].zero_velocity) << columns;
  }
}

// A file-size limit (RLIMIT_FSIZE, SIGXFSZ ignored: the write fails with EFBIG as on a full disk), in a child
// process: every writer throws IoError naming the final file, which does not exist afterwards.
TEST(AtomicFile, AWriteErrorThrowsNamingTheFileAndLeavesNoFinalFile) {
  TempDir dir;
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    std::signal(SIGXFSZ, SIG_IGN);
    const rlimit lim{4096, 4096};
    if (::setrlimit(RLIMIT_FSIZE, &lim) != 0) ::_exit(10);
    int code = 0;
    const auto expect_fails = [&](const std::string& name, const std::function<void(const std::string&)>& write) {
      const std::string path = dir / name;
      try {
        write(path);
        code |= 1;  // no error
      } catch (const IoError& e) {
        if (std::string(e.what()).find(path) == std::string::npos) code |= 2;
      }
      if (fs::exists(path)) code |= 4;
      if (fs::exists(path + ".tmp")) code |= 8;
    };
    nlohmann::json big;
    for (int i = 0; i < 2000; ++i) big["key" + std::to_string(i)] = i;
    expect_fails("summary.json", [&](const std::string& p) { write_summary_json(p, big); });
    Trajectory traj;
    traj.poses.resize(500);
    expect_fails("trajectory.csv", [&](const std::string& p) { write_trajectory_csv(p, traj); });
    expect_fails("trajectory.txt", [&](const std::string& p) { write_tum(p, traj); });
    expect_fails("frames.csv", [&](const std::string& p) {
      FramesCsvWriter w(p);
      for (int i = 0; i < 500; ++i) w.write(FrameStats{});
      w.close();
    });
    ::_exit(code);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "bits: 1 no error, 2 message without the path, 4 final file, 8 tmp left";
}

TEST(ConfigAndSummary, ConfigYamlReloadsAndSummaryJsonParses) {
  TempDir dir;
  YAML::Node cfg;
  cfg["seed"] = 7;
  cfg["filter"]["sigma_pix"] = 0.1;  // a value without an exact short decimal
  cfg["robot"]["type"] = "constant_velocity";
  write_config_yaml(dir / "config.yaml", cfg);
  const YAML::Node back = load_yaml_file(dir / "config.yaml");
  EXPECT_EQ(back["seed"].as<int>(), 7);
  EXPECT_EQ(back["filter"]["sigma_pix"].as<double>(), 0.1);
  EXPECT_EQ(back["robot"]["type"].as<std::string>(), "constant_velocity");

  const Percentiles p = percentiles({5, 1, 4, 2, 3});
  EXPECT_DOUBLE_EQ(p.median, 3.0);
  EXPECT_DOUBLE_EQ(p.p90, 4.6);
  EXPECT_DOUBLE_EQ(p.max, 5.0);
  EXPECT_DOUBLE_EQ(p.mean, 3.0);
  nlohmann::json j;
  j["frames"] = 95;
  j["timing_ms"]["total"] = to_json(p);
  write_summary_json(dir / "summary.json", j);
  const auto parsed = nlohmann::json::parse(test::read_text(dir / "summary.json"));
  EXPECT_EQ(parsed["frames"], 95);
  EXPECT_DOUBLE_EQ(parsed["timing_ms"]["total"]["p90"].get<double>(), 4.6);
  EXPECT_EQ(percentiles({}).count, 0u);
}

TEST(ProgressLine, SilentWhenNotATerminalAndFormatsRateAndEta) {
  std::FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  {
    ProgressLine quiet(100, f);  // a regular file is not a TTY
    EXPECT_FALSE(quiet.enabled());
    for (size_t i = 0; i <= 100; ++i) quiet.update(i);
    quiet.finish();
  }
  EXPECT_EQ(std::ftell(f), 0L);
  {
    ProgressLine forced(10, f, true);
    forced.update(10);
    forced.finish();
  }
  EXPECT_GT(std::ftell(f), 0L);
  std::fclose(f);
  EXPECT_EQ(ProgressLine::format(120, 1000, 4.0), "frames 120/1000 (12%)  30.0 fps  ETA 0:29");
  EXPECT_EQ(ProgressLine::format(7, 0, 1.0), "frames 7  7.0 fps");
}

}  // namespace
}  // namespace rtslam::io
