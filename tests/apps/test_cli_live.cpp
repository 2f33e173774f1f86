// End-to-end tests of the real-time parts of `rtslam run` (issue 16): live input through a video standing in for a
// camera (`--dataset camera:FILE`), its one-line errors, and the search's time budget (`--search-budget`) on a short
// simulated sequence. They run the rtslam executable.
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "rtslam/io/calibration.hpp"

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


/// A video standing in for a camera at rest: the first image of `cam0_data` (a folder of PNGs) as `frames` frames at
/// 20 Hz, MJPG (OpenCV's own encoder). Empty when it cannot be written.
fs::path write_still_video(const fs::path& cam0_data, const fs::path& video, int frames) {
  std::vector<fs::path> pngs;
  for (const auto& e : fs::directory_iterator(cam0_data)) pngs.push_back(e.path());
  std::sort(pngs.begin(), pngs.end());
  if (pngs.empty()) return {};
  const cv::Mat grey = cv::imread(pngs.front().string(), cv::IMREAD_GRAYSCALE);
  if (grey.empty()) return {};
  cv::Mat bgr;
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  cv::VideoWriter w(video.string(), cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 20.0,
                    grey.size(), true);
  if (!w.isOpened()) return {};
  for (int k = 0; k < frames; ++k) w.write(bgr);
  return video;
}

/// Opens a FIFO for writing once a reader (rtslam) has it open (ENXIO before), for at most 60 s; -1 if none came.
/// The descriptor blocks on writes.
int open_fifo_writer(const fs::path& fifo) {
  for (int k = 0; k < 6000; ++k) {
    const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
    if (fd >= 0) {
      ::fcntl(fd, F_SETFL, 0);
      return fd;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return -1;
}

// A live camera paired with a live IMU stream (--imu-stream): the simulator's camera and IMU at rest (a constant pose,
// its synthetic IMU with noise and biases), the video standing in for the camera and the IMU's samples written into a
// FIFO at 200 Hz, stamped on CLOCK_MONOTONIC as a driver on the machine would. The run ends when the writer closes the
// FIFO; the estimate must stay where the rig rests.
TEST(CliLive, ACameraAndItsImuStreamThroughAFifoRunInertialSlamAtRest) {
  const fs::path sim = simulated_sequence();
  const fs::path d = fs::temp_directory_path() / "rtslam_test_cli_live_imu";
  fs::remove_all(d);
  fs::create_directories(d);
  // The handheld sequence's first pose held for 4 s, simulated with its IMU.
  std::string pose;
  {
    std::ifstream gt(sim / "groundtruth.txt");
    std::string line;
    while (std::getline(gt, line) && (line.empty() || line[0] == '#')) {
    }
    pose = line.substr(line.find(' '));
  }
  ASSERT_FALSE(pose.empty());
  {
    std::ofstream tum(d / "static.txt");
    for (int k = 0; k <= 80; ++k) tum << fmt::format("{:.2f}", 0.05 * k) << pose << '\n';
  }
  const fs::path rest = d / "sim";
  const LiveResult simulated = run_cli(fmt::format("simulate --trajectory follow:{} --duration 3.5 --seed 5 --out {}",
                                                   (d / "static.txt").string(), rest.string()));
  ASSERT_EQ(simulated.code, 0) << simulated.out;
  // The camera: the first rendered frame, 20 frames at 20 Hz (the rig does not move), looped by the stand-in.
  const fs::path video = write_still_video(rest / "mav0" / "cam0" / "data", d / "camera.avi", 20);
  ASSERT_FALSE(video.empty());
  // The calibration: camera and IMU in one rig file.
  const fs::path rig = d / "rig.yaml";
  rtslam::io::write_rig_yaml(rig.string(), rtslam::io::load_euroc_folder_calibration((rest / "mav0").string(), {0},
                                                                                     rtslam::io::FolderImu::Required));
  // The IMU's readings, replayed at 200 Hz into the FIFO for 3 s.
  std::vector<std::string> readings;
  {
    std::ifstream csv(rest / "mav0" / "imu0" / "data.csv");
    std::string line;
    while (std::getline(csv, line)) {
      if (!line.empty() && line[0] != '#') readings.push_back(line.substr(line.find(',')));
    }
  }
  ASSERT_GE(readings.size(), 600u);
  const fs::path fifo = d / "imu.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::atomic<int> written{0};
  std::thread writer([&] {
    const int fd = open_fifo_writer(fifo);
    if (fd < 0) return;
    // Each sample stamped with its due time (a driver stamps the sampling, not the writing: a stalled writer
    // thread on a loaded machine must not look like an IMU gap).
    const auto start = std::chrono::steady_clock::now();
    const auto start_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(start.time_since_epoch()).count();
    for (int k = 0; k < 600; ++k) {
      std::this_thread::sleep_until(start + std::chrono::microseconds(5000 * k));
      const std::string line =
          fmt::format("{}{}\n", start_ns + 5'000'000LL * k, readings[static_cast<std::size_t>(k)]);
      if (::write(fd, line.data(), line.size()) != static_cast<ssize_t>(line.size())) break;
      ++written;
    }
    ::close(fd);
  });
  const LiveResult r = run_cli(fmt::format("run --dataset camera:{} --calibration {} --imu-stream {} --config {} "
                                           "--quiet --out {}",
                                           video.string(), rig.string(), fifo.string(),
                                           RTSLAM_SOURCE_DIR "/config/sim_mono_imu.yaml", (d / "out").string()));
  writer.join();
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(written.load(), 600);
  EXPECT_NE(r.out.find("the IMU stream ended (its writer closed it) after 600 lines"), std::string::npos) << r.out;
  const nlohmann::json s = read_json(d / "out" / "summary.json");
  EXPECT_EQ(s["dataset"]["kind"], "camera");
  EXPECT_EQ(s["dataset"]["imu_stream"]["clock"], "host");
  EXPECT_EQ(s["input"]["imu_samples"].get<int>(), 600);  // every sample read reached the filter
  EXPECT_EQ(s["realtime"]["imu_samples"].get<int>(), 600);
  EXPECT_GE(s["realtime"]["images_processed"].get<int>(), 20);  // about 60 in 3 s (fewer when the filter is slow)
  EXPECT_EQ(s["input"]["live_dropped_imu_samples"].get<int>(), 0);
  EXPECT_EQ(s["health"]["final"], "ok");
  // At rest: every estimated position within 5 cm of the first.
  std::ifstream traj(d / "out" / "trajectory.txt");
  std::string line;
  std::vector<Eigen::Vector3d> p;
  while (std::getline(traj, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream in(line);
    double t = 0.0, x = 0.0, y = 0.0, z = 0.0;
    in >> t >> x >> y >> z;
    p.emplace_back(x, y, z);
  }
  ASSERT_GE(p.size(), 20u);
  double drift = 0.0;
  for (const auto& x : p) drift = std::max(drift, (x - p.front()).norm());
  EXPECT_LT(drift, 0.05);
  RecordProperty("drift_m", fmt::format("{:.4f}", drift));
  fs::remove_all(d);
}

/// A live rig whose IMU stream will never deliver: the video standing in for the camera, a rig calibration with an
/// IMU, and the FIFO of the IMU stream (the run's command line: `args`).
struct SilentImuRig {
  fs::path dir, fifo;
  std::string args;
};

SilentImuRig silent_imu_rig(const std::string& name) {
  const fs::path sim = simulated_sequence();
  SilentImuRig r;
  r.dir = fs::temp_directory_path() / name;
  fs::remove_all(r.dir);
  fs::create_directories(r.dir);
  const fs::path video = write_still_video(sim / "mav0" / "cam0" / "data", r.dir / "camera.avi", 10);
  EXPECT_FALSE(video.empty());
  const fs::path rig = r.dir / "rig.yaml";
  rtslam::io::write_rig_yaml(rig.string(), rtslam::io::load_euroc_folder_calibration(
                                               (sim / "mav0").string(), {0}, rtslam::io::FolderImu::Skip));
  {  // (the simulated sequence has no IMU: its calibration is completed with one)
    std::ofstream f(rig, std::ios::app);
    f << "imu:\n  rate_hz: 200\n  gyro_noise_density: 1.7e-4\n  gyro_random_walk: 2e-5\n"
         "  accel_noise_density: 2e-3\n  accel_random_walk: 3e-3\n";
  }
  r.fifo = r.dir / "imu.fifo";
  EXPECT_EQ(::mkfifo(r.fifo.c_str(), 0600), 0);
  r.args = fmt::format("run --dataset camera:{} --calibration {} --imu-stream {} --config {} --quiet --out {}",
                       video.string(), rig.string(), r.fifo.string(), RTSLAM_SOURCE_DIR "/config/sim_mono_imu.yaml",
                       (r.dir / "out").string());
  return r;
}

// An IMU stream whose writer opens it and never writes: the camera's frames are dropped while no sample has come
// (counted), and when the writer closes the stream the run ends with an error saying that no IMU sample came.
TEST(CliLive, AnImuStreamThatNeverDeliversEndsWithAnErrorSayingSo) {
  const SilentImuRig rig = silent_imu_rig("rtslam_test_cli_live_no_imu");
  std::thread writer([&] {
    const int fd = open_fifo_writer(rig.fifo);
    if (fd < 0) return;
    std::this_thread::sleep_for(std::chrono::milliseconds(2000));  // frames wait 0.5 s each, then are dropped
    ::close(fd);
  });
  const LiveResult r = run_cli(rig.args);
  writer.join();
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("no IMU sample came ("), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("camera frame(s) dropped waiting for the first one"), std::string::npos) << r.out;
  fs::remove_all(rig.dir);
}

// --stop-after ends a live run whose IMU stream stays open and silent (nothing is processed before the IMU's first
// sample, so the window of processed times never closes): once the dropped frames span the window, the run ends
// with the same error, while the writer still holds the stream open.
TEST(CliLive, StopAfterEndsARunWhoseImuNeverDelivers) {
  const SilentImuRig rig = silent_imu_rig("rtslam_test_cli_live_no_imu_stop_after");
  std::mutex mu;
  std::condition_variable cv;
  bool run_ended = false, writer_closed_first = false;
  std::thread writer([&] {
    const int fd = open_fifo_writer(rig.fifo);
    if (fd < 0) return;
    std::unique_lock lock(mu);
    // Held open until the run has ended (at most 120 s: a run that does not end on its own then ends with it).
    if (!cv.wait_for(lock, std::chrono::seconds(120), [&] { return run_ended; })) writer_closed_first = true;
    ::close(fd);
  });
  const LiveResult r = run_cli(rig.args + " --stop-after 1");
  {
    std::lock_guard lock(mu);
    run_ended = true;
  }
  cv.notify_all();
  writer.join();
  EXPECT_FALSE(writer_closed_first) << "the run did not end before its IMU stream was closed";
  EXPECT_NE(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("no IMU sample in the 1 s of input to process"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("no IMU sample came ("), std::string::npos) << r.out;
  fs::remove_all(rig.dir);
}

// The pairing's one-line errors: an IMU stream without an inertial configuration, with a non-live dataset, a
// calibration without the IMU, a stream that does not exist.
TEST(CliLive, ImuStreamErrorsAreOneLine) {
  const fs::path sim = simulated_sequence();
  const std::string camera_calibration = (sim / "mav0" / "cam0" / "sensor.yaml").string();
  const fs::path d = fs::temp_directory_path() / "rtslam_test_cli_live_imu_errors";
  fs::remove_all(d);
  const std::string inertial = RTSLAM_SOURCE_DIR "/config/sim_mono_imu.yaml";
  const auto expect_error = [&](const std::string& args, const std::string& message) {
    const LiveResult r = run_cli(args + " --out " + (d / "x").string());
    EXPECT_NE(r.code, 0) << args;
    EXPECT_EQ(count_newlines(r.out), 1) << r.out;
    EXPECT_NE(r.out.find(message), std::string::npos) << r.out;
  };
  expect_error(fmt::format("run --dataset camera:0 --calibration {} --imu-stream -", camera_calibration),
               "--imu-stream -: the configuration's robot is constant_velocity, which reads no IMU");
  expect_error(fmt::format("run --dataset euroc:{} --config {} --imu-stream -", sim.string(), inertial),
               "--imu-stream pairs a live IMU with a camera:N input only");
  expect_error(fmt::format("run --dataset camera:0 --calibration {} --config {}", camera_calibration, inertial),
               "a live camera streams no IMU, which slam/robot: inertial needs: pair one with --imu-stream");
  expect_error(fmt::format("run --dataset camera:0 --calibration {} --config {} --imu-stream -", camera_calibration,
                           inertial),
               camera_calibration + ": no IMU in this calibration, which --imu-stream needs");
  expect_error(fmt::format("run --dataset camera:0 --calibration {} --imu-clock device", camera_calibration),
               "--imu-clock applies to --imu-stream only");
  fs::remove_all(d);
}

}  // namespace
