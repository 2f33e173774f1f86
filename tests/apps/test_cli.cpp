// End-to-end tests of the rtslam command line: exit codes, one-line errors, outputs, reproducibility.
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

namespace {

namespace fs = std::filesystem;

struct Result {
  int code = -1;
  std::string out;  // stdout and stderr
};

Result run(const std::string& args) {
  const std::string cmd = std::string(RTSLAM_CLI) + " " + args + " 2>&1";
  Result r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf{};
  while (fgets(buf.data(), static_cast<int>(buf.size()), p)) r.out += buf.data();
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string read_file(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

fs::path temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("rtslam_test_cli_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

int count_lines(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

TEST(Cli, EverySubcommandHasHelp) {
  for (const char* sub : {"run", "simulate", "eval", "batch", "report", "bench", "imu-noise"}) {
    const Result r = run(std::string(sub) + " --help");
    EXPECT_EQ(r.code, 0) << sub << ": " << r.out;
    EXPECT_NE(r.out.find("Usage"), std::string::npos) << sub;
  }
  const Result none = run("");
  EXPECT_NE(none.code, 0) << "a subcommand is required";
}

TEST(Cli, DemoRunWritesOutputsAndItsConfigReproducesIt) {
  const fs::path a = temp_dir("demo_a");
  const fs::path b = temp_dir("demo_b");
  const Result r = run("run --duration 6 --seed 3 --quiet --out " + a.string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("ATE"), std::string::npos);
  for (const char* f : {"trajectory.txt", "trajectory.csv", "groundtruth.txt", "frames.csv", "summary.json",
                        "config.yaml", "map.ply"}) {
    EXPECT_TRUE(fs::exists(a / f)) << f;
  }
  // TUM text: 8 numbers per line, no header surprises.
  std::istringstream traj(read_file(a / "trajectory.txt"));
  std::string line;
  int rows = 0;
  while (std::getline(traj, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    double v;
    int n = 0;
    while (ls >> v) ++n;
    EXPECT_EQ(n, 8) << line;
    ++rows;
  }
  EXPECT_GT(rows, 100);
  // The timing report: per-frame percentiles and the stage medians, the matching stage measured.
  const std::string summary = read_file(a / "summary.json");
  EXPECT_NE(summary.find("\"timing_ms\""), std::string::npos);
  EXPECT_NE(summary.find("\"timing_stage_median_ms\""), std::string::npos);
  EXPECT_NE(r.out.find("stage medians: predict"), std::string::npos) << r.out;
  const Result r2 = run("run --config " + (a / "config.yaml").string() + " --quiet --out " + b.string());
  ASSERT_EQ(r2.code, 0) << r2.out;
  EXPECT_EQ(read_file(a / "trajectory.txt"), read_file(b / "trajectory.txt"));
}

TEST(Cli, PointsDemoRunsTheKnownAssociationSkeleton) {
  const fs::path a = temp_dir("points");
  const Result r = run("run --points-demo --duration 4 --seed 3 --quiet --out " + a.string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("known association"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(a / "trajectory.txt"));
  const Result bad = run("run --points 30 --quiet --out " + a.string());
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.out.find("--points-demo"), std::string::npos) << bad.out;
}

TEST(Cli, MissingConfigIsOneLineErrorNamingTheFile) {
  const Result r = run("run --config /nonexistent/dir/cfg.yaml");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("/nonexistent/dir/cfg.yaml"), std::string::npos) << r.out;
  EXPECT_EQ(count_lines(r.out), 1) << r.out;
}

TEST(Cli, BrokenYamlIsOneLineErrorNamingTheFile) {
  const fs::path d = temp_dir("broken");
  std::ofstream(d / "bad.yaml") << "demo: {seed: [1, 2\n";
  const Result r = run("run --config " + (d / "bad.yaml").string());
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("bad.yaml"), std::string::npos) << r.out;
  EXPECT_EQ(count_lines(r.out), 1) << r.out;
  std::ofstream(d / "unknown.yaml") << "slam:\n  sead: 3\n";
  const Result u = run("run --config " + (d / "unknown.yaml").string());
  EXPECT_NE(u.code, 0);
  EXPECT_NE(u.out.find("sead"), std::string::npos) << u.out;
}

TEST(Cli, DumpConfigPrintsTheEffectiveConfiguration) {
  const Result r = run("run --dump-config --seed 9");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("seed: 9"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("d_min"), std::string::npos);
}

TEST(Cli, ImuNoiseWithoutGroundTruthIsOneLineNamingTheStateFile) {
  const fs::path d = temp_dir("imu_noise_nogt");
  fs::create_directories(d / "mav0" / "imu0");
  std::ofstream(d / "mav0" / "imu0" / "data.csv") << "#t,wx,wy,wz,ax,ay,az\n0,0,0,0,0,0,9.81\n";
  const Result r = run("imu-noise --dataset euroc:" + d.string());
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("state_groundtruth_estimate0/data.csv"), std::string::npos) << r.out;
  EXPECT_EQ(count_lines(r.out), 1) << r.out;
  const Result missing = run("imu-noise --dataset euroc:" + (d / "absent").string());
  EXPECT_NE(missing.code, 0);
  EXPECT_EQ(count_lines(missing.out), 1) << missing.out;
  const Result bad = run("imu-noise --dataset euroc:" + d.string() + " --windows 0.05,-1");
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.out.find("window"), std::string::npos) << bad.out;
}

TEST(Cli, ImuNoiseOnTheRecordedV101FlightGivesThePresetsDensities) {
  const fs::path data = "../shared/datasets/euroc-v101-static";
  if (!fs::is_directory(data)) GTEST_SKIP() << data << " not found (../shared/datasets/README.md)";
  const fs::path d = temp_dir("imu_noise_v101");
  const Result r = run("imu-noise --dataset euroc:" + data.string() + " --json " + (d / "noise.json").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("in flight"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("accelerometer_noise_density:"), std::string::npos) << r.out;
  // config/euroc_mono_imu.yaml: accelerometer 7.0e-3 m/s²/√Hz, gyroscope 3.4e-4 rad/s/√Hz (50 ms, in flight).
  const std::string j = read_file(d / "noise.json");
  const auto number_after = [&](const std::string& key) {
    const auto k = j.find("\"" + key + "\"");
    return k == std::string::npos ? 0.0 : std::stod(j.substr(j.find(':', k) + 1));
  };
  EXPECT_NEAR(number_after("accelerometer_noise_density") / 7.0e-3, 1.0, 0.1) << j;
  EXPECT_NEAR(number_after("gyroscope_noise_density") / 3.4e-4, 1.0, 0.1) << j;
}

}  // namespace
