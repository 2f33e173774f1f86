// End-to-end tests of the real-time parts of `rtslam run` (issue 16): live input through a video standing in for a
// camera (`--dataset camera:FILE`), its one-line errors, and the search's time budget (`--search-budget`) on a short
// simulated sequence. They run the rtslam executable.
#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <sys/wait.h>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

namespace {

namespace fs = std::filesystem;

struct LiveResult {
  int code = -1;
  std::string out;  // stdout and stderr
};

LiveResult run_cli(const std::string& args) {
  const std::string cmd = std::string(RTSLAM_CLI) + " " + args + " 2>&1";
  LiveResult r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf{};
  while (fgets(buf.data(), static_cast<int>(buf.size()), p)) r.out += buf.data();
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

nlohmann::json read_json(const fs::path& p) {
  std::ifstream f(p);
  return nlohmann::json::parse(f);
}

int count_newlines(const std::string& s) {
  int n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

/// 1.2 simulated seconds (camera only, the handheld preset) as an EuRoC folder, shared by the tests of this file.
const fs::path& simulated_sequence() {
  static const fs::path dir = [] {
    const fs::path d = fs::temp_directory_path() / "rtslam_test_cli_live_sim";
    fs::remove_all(d);
    const LiveResult r = run_cli(fmt::format("simulate --no-imu --duration 1.2 --seed 3 --out {}", d.string()));
    EXPECT_EQ(r.code, 0) << r.out;
    return d;
  }();
  return dir;
}

TEST(CliLive, AVideoStandingInForTheCameraIsProcessedInALoopUntilStopAfter) {
  const fs::path sim = simulated_sequence();
  const fs::path d = fs::temp_directory_path() / "rtslam_test_cli_live_camera";
  fs::remove_all(d);
  fs::create_directories(d);
  // The first 12 rendered frames as a palindromic MJPG AVI (0 … 11 … 1: the loop has no jump), OpenCV's own encoder.
  std::vector<fs::path> pngs;
  for (const auto& e : fs::directory_iterator(sim / "mav0" / "cam0" / "data")) pngs.push_back(e.path());
  std::sort(pngs.begin(), pngs.end());
  ASSERT_GE(pngs.size(), 12u);
  pngs.resize(12);
  const cv::Mat first = cv::imread(pngs.front().string(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(first.empty());
  const fs::path video = d / "camera.avi";
  {
    cv::VideoWriter w(video.string(), cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 20.0,
                      first.size(), true);
    ASSERT_TRUE(w.isOpened());
    std::vector<std::size_t> order;
    for (std::size_t i = 0; i < pngs.size(); ++i) order.push_back(i);
    for (std::size_t i = pngs.size() - 2; i >= 1; --i) order.push_back(i);
    for (std::size_t i : order) {
      cv::Mat bgr;
      cv::cvtColor(cv::imread(pngs[i].string(), cv::IMREAD_GRAYSCALE), bgr, cv::COLOR_GRAY2BGR);
      w.write(bgr);
    }
  }
  const std::size_t loop_frames = 2 * pngs.size() - 2;
  const std::string calibration = (sim / "mav0" / "cam0" / "sensor.yaml").string();
  // Played at 30 Hz (recorded at 20 Hz) for 1.5 s of input: about 45 frames, two loops.
  const LiveResult r = run_cli(fmt::format("run --dataset camera:{} --calibration {} --rate 30 --stop-after 1.5 "
                                           "--config {} --quiet --out {}",
                                           video.string(), calibration, RTSLAM_SOURCE_DIR "/config/sim_mono.yaml",
                                           (d / "out").string()));
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json s = read_json(d / "out" / "summary.json");
  EXPECT_EQ(s["dataset"]["kind"], "camera");
  EXPECT_EQ(s["realtime"]["live"], true);
  const int processed = s["realtime"]["images_processed"].get<int>();
  const int released = s["realtime"]["images_released"].get<int>();
  EXPECT_GT(released, static_cast<int>(loop_frames));  // looped
  EXPECT_GE(processed, 20);
  EXPECT_EQ(processed + s["realtime"]["images_dropped"].get<int>(), released);
  EXPECT_EQ(s["frames"].get<int>(), processed);
  // Live: the search budget is half the frame period (30 Hz: 16.7 ms).
  EXPECT_EQ(s["search_budget"]["source"], "--realtime");
  EXPECT_NEAR(s["search_budget"]["budget_ms"].get<double>(), 1e3 / 30.0 / 2.0, 1e-9);
  EXPECT_GT(s["landmarks"]["created"].get<int>(), 0);
  // It tracks: most frames correct with landmarks (at the palindrome's turns, where the motion reverses at once, the
  // constant-velocity prediction can miss for a few frames, more of them when a loaded machine drops frames).
  std::ifstream csv(d / "out" / "frames.csv");
  std::string line;
  std::getline(csv, line);
  int tracked = 0, rows = 0;
  while (std::getline(csv, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    ASSERT_GE(f.size(), 7u) << line;
    ++rows;
    tracked += std::stoi(f[6]) >= 10 ? 1 : 0;  // updated
  }
  EXPECT_EQ(rows, processed);
  EXPECT_GT(2 * tracked, rows);
  RecordProperty("tracked_frames", fmt::format("{} of {}", tracked, rows));
  fs::remove_all(d);
}

TEST(CliLive, CameraErrorsAreOneLine) {
  const fs::path sim = simulated_sequence();
  const std::string calibration = (sim / "mav0" / "cam0" / "sensor.yaml").string();
  const fs::path d = fs::temp_directory_path() / "rtslam_test_cli_live_errors";
  fs::remove_all(d);
  const LiveResult no_calib = run_cli(fmt::format("run --dataset camera:0 --out {}", (d / "a").string()));
  EXPECT_NE(no_calib.code, 0);
  EXPECT_EQ(count_newlines(no_calib.out), 1) << no_calib.out;
  EXPECT_NE(no_calib.out.find("camera:0: a live camera needs its calibration: give --calibration FILE"),
            std::string::npos)
      << no_calib.out;
  const LiveResult no_device =
      run_cli(fmt::format("run --dataset camera:63 --calibration {} --out {}", calibration, (d / "b").string()));
  EXPECT_NE(no_device.code, 0);
  EXPECT_EQ(count_newlines(no_device.out), 1) << no_device.out;
  EXPECT_NE(no_device.out.find("/dev/video63: no such camera device"), std::string::npos) << no_device.out;
  const LiveResult speed = run_cli(fmt::format("run --dataset camera:0 --calibration {} --realtime 10 --out {}",
                                               calibration, (d / "c").string()));
  EXPECT_NE(speed.code, 0);
  EXPECT_EQ(count_newlines(speed.out), 1) << speed.out;
  EXPECT_NE(speed.out.find("a live camera runs at its own clock"), std::string::npos) << speed.out;
  fs::remove_all(d);
}

// A tiny search budget (a quarter of the unbudgeted run's median search time: a few ZNCC searches) on the 1.2
// simulated seconds: the run still tracks, with fewer searches, and says how often the budget cut the search. The
// budget is taken from the run itself because the search's speed is the build's and the machine's: a fixed 0.05 ms
// (about a third of the Release search) left frames without a single match under the sanitizers on a busy machine.
TEST(CliLive, ATinySearchBudgetCutsTheSearchAndTheRunStillTracks) {
  const fs::path sim = simulated_sequence();
  const fs::path d = fs::temp_directory_path() / "rtslam_test_cli_live_budget";
  fs::remove_all(d);
  const std::string common =
      fmt::format("run --dataset euroc:{} --config {} --quiet", sim.string(), RTSLAM_SOURCE_DIR "/config/sim_mono.yaml");
  const LiveResult off = run_cli(common + " --out " + (d / "off").string());
  ASSERT_EQ(off.code, 0) << off.out;
  const nlohmann::json a = read_json(d / "off" / "summary.json");
  EXPECT_EQ(a["search_budget"]["budget_ms"].get<double>(), 0.0);
  EXPECT_EQ(a["search_budget"]["frames_hit"].get<int>(), 0);
  const double search_median_ms = a["search_budget"]["search_ms"]["median"].get<double>();
  ASSERT_GT(search_median_ms, 0.0);
  const std::string budget = fmt::format("{:.3g}", 0.25 * search_median_ms);
  const LiveResult tiny = run_cli(common + " --search-budget " + budget + " --out " + (d / "tiny").string());
  ASSERT_EQ(tiny.code, 0) << tiny.out;
  EXPECT_NE(tiny.out.find("search budget " + budget + " ms (--search-budget): ran out in "), std::string::npos)
      << tiny.out;
  // Not real time: the user is told that the result now depends on the machine's speed.
  EXPECT_NE(tiny.out.find("on a run that is not real time"), std::string::npos) << tiny.out;
  EXPECT_EQ(off.out.find("on a run that is not real time"), std::string::npos) << off.out;
  const nlohmann::json b = read_json(d / "tiny" / "summary.json");
  EXPECT_EQ(b["search_budget"]["budget_ms"].get<double>(), std::stod(budget));
  EXPECT_GT(b["search_budget"]["frames_hit"].get<int>(), 0);
  EXPECT_GT(b["search_budget"]["landmarks_skipped"].get<int>(), 0);
  EXPECT_EQ(b["frames"], a["frames"]);
  EXPECT_EQ(b["health"]["final"], "ok");
  EXPECT_GT(b["matched_min_after_1s"].get<int>(), 0);
  // frames.csv: the per-frame columns agree with the summary.
  std::ifstream csv(d / "tiny" / "frames.csv");
  std::string line;
  std::getline(csv, line);
  EXPECT_NE(line.find(",budget_hit,budget_skipped,t_search [ms]"), std::string::npos) << line;
  const auto columns = static_cast<size_t>(std::count(line.begin(), line.end(), ',') + 1);  // as the header has
  int hit = 0;
  while (std::getline(csv, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    ASSERT_EQ(f.size(), columns) << line;
    hit += std::stoi(f[21]);
  }
  EXPECT_EQ(hit, b["search_budget"]["frames_hit"].get<int>());
  fs::remove_all(d);
}

}  // namespace
