// rtslam run: monocular image SLAM (src/rtslam/pipeline/image_slam.hpp, docs/configuration.md) on a dataset's
// camera, or, without --dataset (or with --dataset sim:PRESET), on the simulator's images rendered on the fly
// (default preset: handheld). It writes config.yaml, trajectory.txt, trajectory.csv, groundtruth.txt (when the
// input has one), frames.csv, map.ply, summary.json and, with --overlay-frame, a PNG overlay. What users see
// (src/rtslam/viz, docs/viewer.md): --view serves the live web viewer while the run goes, --overlays writes one
// overlay PNG per processed frame (every Nth with --overlay-every), --video the overlays as a video; all three are
// fed by run_image_slam's observer on the filter thread (viz::make_report shares the image, push never blocks).
// --points-demo runs the walking skeleton instead: simulated point measurements with known association
// (src/rtslam/pipeline/point_demo.hpp), which writes trajectory.txt, trajectory.csv, groundtruth.txt, frames.csv
// and summary.json.
// Crash safety (docs/outputs.md): every file is written as NAME.tmp and renamed when complete; trajectory.csv and
// frames.csv stream into their .tmp during the run; an --out holding an earlier run's files is refused unless
// --force (which removes exactly those files); SIGINT/SIGTERM stop the run at the next measurement, the outputs of
// what was processed are written with summary.json "status": "interrupted" and the exit code is 130/143; an error
// during the run writes summary.json with "status": "failed" and the error.
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <functional>
#include <iostream>
#include <limits>
#include <optional>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "calibration_prepass.hpp"
#include "commands.hpp"
#include "prefetch_option.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/eval/metrics.hpp"
#include "rtslam/eval/run_eval.hpp"
#include "rtslam/io/trajectory_io.hpp"
#include "rtslam/io/writers.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/realtime.hpp"
#include "rtslam/pipeline/default_config.hpp"
#include "rtslam/pipeline/demo_config.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/pipeline/point_demo.hpp"
#include "rtslam/sim/point_scene.hpp"
#include "rtslam/viz/overlay.hpp"
#include "rtslam/viz/report.hpp"
#include "rtslam/viz/viewer.hpp"

namespace rtslam::cli {
namespace {

struct RunOptions {
  std::string dataset;
  std::string config;
  bool dump_config = false;
  std::string out = "rtslam-out";
  std::optional<std::uint64_t> seed;
  std::optional<double> duration_s;
  std::optional<double> rate_hz;
  double start_at_s = 0.0;
  double stop_after_s = 0.0;
  std::string groundtruth;
  std::optional<int> points;
  std::optional<int> overlay_frame;
  bool points_demo = false;
  bool quiet = false;
  // What users see (docs/viewer.md).
  std::optional<std::string> view;     // --view [ADDR:PORT]: serve the live viewer on this address
  std::optional<double> view_hold_s;   // after the run: serve this many seconds (default: until Ctrl-C)
  double view_wait_s = 0.0;            // before the run: wait up to this long for a browser to connect
  std::optional<std::string> overlays;  // --overlays [DIR]: PNG per frame (empty: OUT/overlays)
  int overlay_every = 1;
  std::string video;                   // --video FILE
  bool force = false;                  // --force: replace the outputs of an earlier run in --out
  io::DatasetOptions input;            // --bad-input, --calibration, --timestamps, --max-imu-dropout, bag topics
  std::optional<double> realtime;      // --realtime [SPEED]: replay at the sensor clock × SPEED, drop late images
  std::optional<double> search_budget_ms;  // --search-budget MS: search/time_budget_ms (0: off)
  int prefetch = -1;                   // --prefetch N / --no-prefetch (prefetch_option.hpp)
};

// The files of a run in --out (and their .tmp), besides overlays/, overlay_NNNNN.png and the --video file there.
constexpr std::array<const char*, 7> kRunFiles = {"config.yaml", "trajectory.txt", "trajectory.csv", "groundtruth.txt",
                                                  "frames.csv",  "map.ply",        "summary.json"};

// overlay_NNNNN.png (--overlay-frame) or its .tmp. (No std::regex: GCC 12's -O1 sanitizer build warns inside it.)
bool is_overlay_png_name(const std::string& n) {
  constexpr std::string_view prefix = "overlay_";
  if (n.size() < prefix.size() + 9 || n.compare(0, prefix.size(), prefix) != 0) return false;
  for (std::size_t k = prefix.size(); k < prefix.size() + 5; ++k)
    if (n[k] < '0' || n[k] > '9') return false;
  const std::string rest = n.substr(prefix.size() + 5);
  return rest == ".png" || rest == ".png.tmp";
}

// No mixed runs: the outputs of an earlier run in --out are refused (one line naming them), or removed with --force
// (exactly those: other files stay). Then creates --out.
void prepare_out_dir(const RunOptions& ro) {
  namespace fs = std::filesystem;
  const fs::path out(ro.out);
  std::vector<fs::path> ours;
  std::error_code ec;
  if (fs::is_directory(out, ec)) {
    for (const char* f : kRunFiles) {
      for (const fs::path& p : {out / f, out / (std::string(f) + ".tmp")}) {
        if (fs::exists(fs::symlink_status(p, ec))) ours.push_back(p);
      }
    }
    if (fs::exists(out / "overlays", ec)) ours.push_back(out / "overlays");
    for (const auto& e : fs::directory_iterator(out, ec)) {
      if (is_overlay_png_name(e.path().filename().string())) ours.push_back(e.path());
    }
    if (!ro.video.empty() && fs::exists(ro.video, ec) &&
        fs::weakly_canonical(fs::path(ro.video).parent_path(), ec) == fs::weakly_canonical(out, ec)) {
      ours.push_back(ro.video);
    }
  }
  if (!ours.empty() && !ro.force) {
    std::string names;
    for (size_t i = 0; i < ours.size() && i < 4; ++i) names += (i ? ", " : "") + ours[i].filename().string();
    if (ours.size() > 4) names += ", ...";
    throw IoError(
        fmt::format("{}: holds the outputs of an earlier run ({}); rerun with --force to replace them, or "
                    "choose another --out",
                    ro.out, names));
  }
  for (const auto& p : ours) {
    fs::remove_all(p, ec);
    if (ec) throw IoError(fmt::format("{}: cannot remove it (--force): {}", p.string(), ec.message()));
  }
  fs::create_directories(out, ec);
  if (ec) throw IoError(fmt::format("{}: cannot create the output folder: {}", ro.out, ec.message()));
}

// SIGINT / SIGTERM during a run: the handler sets the flags; the pipeline stops at the next measurement.
std::atomic<bool> g_run_stop{false};
std::atomic<int> g_run_signal{0};
extern "C" void on_run_signal(int sig) {
  g_run_signal = sig;
  g_run_stop = true;
}

/// Installs on_run_signal for SIGINT and SIGTERM while alive (or until restore()).
class RunSignals {
 public:
  RunSignals() {
    g_run_stop = false;
    g_run_signal = 0;
    old_int_ = std::signal(SIGINT, on_run_signal);
    old_term_ = std::signal(SIGTERM, on_run_signal);
  }
  ~RunSignals() { restore(); }
  RunSignals(const RunSignals&) = delete;
  RunSignals& operator=(const RunSignals&) = delete;
  void restore() {
    if (restored_) return;
    restored_ = true;
    std::signal(SIGINT, old_int_ == SIG_ERR ? SIG_DFL : old_int_);
    std::signal(SIGTERM, old_term_ == SIG_ERR ? SIG_DFL : old_term_);
  }
  /// The signal received (0: none); exit code 128 + signal.
  static int received() { return g_run_signal.load(); }

 private:
  using Handler = void (*)(int);
  Handler old_int_ = SIG_DFL, old_term_ = SIG_DFL;
  bool restored_ = false;
};

const char* signal_name(int sig) { return sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "a signal"; }

// Ctrl-C / SIGTERM while the viewer keeps serving after the run (names distinct from cmd_view's: unity build).
std::atomic<bool> g_run_viewer_stop{false};
extern "C" void on_run_viewer_signal(int) { g_run_viewer_stop = true; }

// --view, --overlays, --video: the run's observer. Opened before the run, so that a port in use, an unwritable
// folder or an unknown video extension fail at once with one line (IoError naming the address or the path); a
// codec OpenCV lacks fails at the second frame (the video opens when it knows the rate).
class RunDisplays {
 public:
  RunDisplays(const RunOptions& ro, const pipeline::ImageSlamOptions& o) {
    viz::OverlayOptions oo;
    oo.n_sigma = o.search.n_sigma;  // the drawn ellipse is the searched one
    every_ = ro.overlay_every;
    if (ro.overlays) overlays_.emplace(ro.overlays->empty() ? ro.out + "/overlays" : *ro.overlays, oo);
    if (!ro.video.empty()) video_.emplace(ro.video, 0.0, oo);
    video_file_ = ro.video;
    if (ro.view) {
      viz::ViewerOptions vo;
      vo.address = ro.view->empty() ? std::string("127.0.0.1:0") : *ro.view;
      vo.overlay = oo;
      vo.validate();
      viewer_.emplace(vo);
      std::cout << "viewer: " << viewer_->url() << std::endl;
      if (ro.view_wait_s > 0.0) wait_for_browser(ro.view_wait_s);
    }
  }
  /// --view-wait: a demo (or a test) that must show the run from its first frame waits for a browser.
  void wait_for_browser(double seconds) {
    std::cout << fmt::format("viewer: waiting up to {:g} s for a browser", seconds) << std::endl;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (viewer_->stats().clients == 0 && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    std::cout << (viewer_->stats().clients > 0 ? "viewer: a browser is connected; the run starts"
                                               : "viewer: no browser connected; the run starts anyway")
              << std::endl;
  }
  /// The run's input, once opened: the page's title and ground truth.
  void attach(const io::Dataset& ds, std::uint64_t seed) {
    if (viewer_) {
      viewer_->set_title(fmt::format("{} ({}), seed {}", ds.name, ds.kind, seed));
      if (ds.ground_truth) viewer_->set_ground_truth(*ds.ground_truth);
    }
    const auto total = ds.source->image_count();
    if (total) observer_us_.reserve(*total);
  }
  bool active() const { return viewer_ || overlays_ || video_; }

  /// On the filter thread, after each processed image.
  void on_frame(const pipeline::ImageSlamFrame& f) {
    const bool png = overlays_ && f.index % every_ == 0;
    if (!png && !video_ && !viewer_) return;
    const auto t0 = std::chrono::steady_clock::now();
    viz::FrameReport r = viz::make_report(f, *f.image, f.stats, f.grid);
    if (png) overlays_->write(r);
    if (video_) video_->write(r);
    if (viewer_) viewer_->push(std::move(r));
    observer_us_.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count());
  }

  /// After the run: closes the files (errors surface here) and tells the browsers the run has ended.
  void finish_run() {
    if (overlays_) overlays_->close();
    if (video_) video_->close();
    if (viewer_) viewer_->finish();
  }

  /// One line for the run's report ("" when nothing is shown) and the summary's "viz" entry.
  std::string report_line(nlohmann::json& summary) const {
    if (!active()) return {};
    const io::Percentiles p = io::percentiles(observer_us_);
    nlohmann::json j = {{"observer_us", io::to_json(p)}};
    std::string what;
    if (viewer_) {
      const viz::ViewerStats vs = viewer_->stats();
      j["viewer"] = {{"url", viewer_->url()}, {"pushed", vs.pushed}, {"dropped", vs.dropped},
                     {"frames_sent", vs.frames_sent}};
      what += fmt::format("viewer {} ({} frames pushed, {} skipped by the viewer)", viewer_->url(), vs.pushed,
                          vs.dropped);
    }
    if (overlays_) {
      j["overlays"] = {{"dir", overlays_->dir()}, {"frames", overlays_->frames_written()}, {"every", every_}};
      what += fmt::format("{}{} overlay PNGs in {}/", what.empty() ? "" : ", ", overlays_->frames_written(),
                          overlays_->dir());
    }
    if (video_) {
      j["video"] = {{"file", video_file_}, {"frames", video_->frames_written()}};
      what += fmt::format("{}video {} ({} frames)", what.empty() ? "" : ", ", video_file_, video_->frames_written());
    }
    summary["viz"] = j;
    return fmt::format("  display: {}; observer {:.1f} us per frame (median; p90 {:.1f}, max {:.1f})\n", what,
                       p.median, p.p90, p.max);
  }

  /// --view: keeps serving after the run until Ctrl-C / SIGTERM, or for --view-hold seconds.
  void hold(const RunOptions& ro) {
    if (!viewer_) return;
    if (ro.view_hold_s && *ro.view_hold_s <= 0.0) return;
    g_run_viewer_stop = false;
    std::signal(SIGINT, on_run_viewer_signal);
    std::signal(SIGTERM, on_run_viewer_signal);
    std::cout << "viewer: the run has ended; still serving " << viewer_->url()
              << (ro.view_hold_s ? fmt::format(" for {:g} s", *ro.view_hold_s) : std::string(" until Ctrl-C"))
              << std::endl;
    const auto start = std::chrono::steady_clock::now();
    while (!g_run_viewer_stop) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      if (ro.view_hold_s &&
          std::chrono::steady_clock::now() - start > std::chrono::duration<double>(*ro.view_hold_s)) {
        break;
      }
    }
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
    viewer_->stop();
    std::cout << "viewer: stopped" << std::endl;
  }

 private:
  int every_ = 1;
  std::optional<viz::OverlayWriter> overlays_;
  std::optional<viz::VideoWriter> video_;
  std::optional<viz::Viewer> viewer_;
  std::string video_file_;
  std::vector<double> observer_us_;
};

/// `camera`: the rig's index of the frame's camera (with several cameras, a frame merges one time's images: the
/// first of them).
io::FrameStats to_io(const slam::FrameStats& s, int camera) {
  io::FrameStats f;
  f.t = s.t;
  f.camera = camera;
  f.landmarks = s.landmarks_in_map;
  f.predicted_visible = s.visible;
  f.searched = s.searched;
  f.matched = s.matched;
  f.updated = s.updated;
  f.initialized = s.initialized;
  f.ransac_inliers = s.ransac_inliers;
  f.t_predict_ms = s.time_predict_ms;
  f.t_match_ms = s.time_match_ms;
  f.t_ransac_ms = s.time_ransac_ms;
  f.t_update_ms = s.time_update_ms;
  f.t_init_ms = s.time_init_ms;
  f.t_map_ms = s.time_map_ms;
  f.t_total_ms = s.time_total_ms;
  f.refused = s.refused;
  f.nis = s.nis;
  f.nis_count = s.nis_count;
  f.health = s.health;
  f.reset = s.reset;
  f.budget_hit = s.budget_hit;
  f.budget_skipped = s.budget_skipped;
  f.t_search_ms = s.time_search_ms;
  f.absolute_updates = s.absolute_updates;
  f.absolute_rejected = s.absolute_rejected;
  f.search_fallback = s.fallback;
  f.zero_velocity = s.zero_velocity;
  return f;
}

void run_demo(const RunOptions& ro) {
  pipeline::PointDemoOptions o = ro.config.empty() ? pipeline::PointDemoOptions{} : pipeline::load_demo_config(ro.config);
  if (ro.seed) o.seed = *ro.seed;
  if (ro.duration_s) o.duration_s = *ro.duration_s;
  if (ro.rate_hz) o.rate_hz = *ro.rate_hz;
  if (ro.points) o.n_points = *ro.points;
  o.validate();
  if (ro.dump_config) {
    std::cout << YAML::Dump(pipeline::to_yaml(o)) << '\n';
    return;
  }
  prepare_out_dir(ro);
  io::write_config_yaml(ro.out + "/config.yaml", pipeline::to_yaml(o), "--points-demo");

  io::ProgressLine progress(0, nullptr, ro.quiet ? std::optional<bool>(false) : std::nullopt);
  sim::PointScene scene(o.scene());
  const auto result =
      pipeline::run_point_demo(o, scene, [&](int done, int) { progress.update(static_cast<size_t>(done)); });
  progress.finish();
  const Trajectory groundtruth = scene.groundtruth();  // the simulator's truth, for scoring the finished run

  io::write_tum(ro.out + "/trajectory.txt", result.estimate);
  io::write_trajectory_csv(ro.out + "/trajectory.csv", result.estimate);
  io::write_tum(ro.out + "/groundtruth.txt", groundtruth);
  {
    io::FramesCsvWriter frames(ro.out + "/frames.csv");
    for (const auto& s : result.frames) frames.write(to_io(s, 0));
    frames.close();
  }
  std::vector<double> times;
  times.reserve(result.frames.size());
  for (const auto& s : result.frames) times.push_back(s.time_total_ms);
  const io::Percentiles timing = io::percentiles(times);

  eval::EvalOptions eo;
  eo.align = eval::Alignment::Sim3;
  eo.with_rpe = false;
  const eval::EvalResult ev = eval::evaluate(result.estimate, groundtruth, eo);
  const double ate = ev.ate.trans_m.rmse;
  const double ate_pct = ev.path_length_m > 0 ? 100.0 * ate / ev.path_length_m : 0.0;

  nlohmann::json summary;
  summary["status"] = "complete";
  summary["mode"] = "demo: simulated points, known association, constant-velocity monocular EKF-SLAM";
  summary["seed"] = o.seed;
  summary["frames"] = result.frames.size();
  summary["landmarks"] = {{"final", result.landmarks_final},
                          {"created", result.landmarks_created},
                          {"euclidean_final", result.euclidean_final}};
  summary["timing_ms"] = io::to_json(timing);
  summary["accuracy"] = eval::to_json(ev, eo);
  summary["ate_percent_of_path"] = ate_pct;
  io::write_summary_json(ro.out + "/summary.json", summary);

  std::cout << fmt::format(
      "rtslam points demo (simulated points, known association; seed {}): {} frames, {:.1f} s\n"
      "  landmarks: {} in map at the end ({} Euclidean), {} created\n"
      "  per-frame time: median {:.3f} ms, p90 {:.3f} ms, max {:.3f} ms\n"
      "  ATE (Sim(3) aligned): RMSE {:.4f} m = {:.3f} % of the {:.2f} m path; estimated scale {:.4f}\n"
      "  outputs in {}/\n",
      o.seed, result.frames.size(), o.duration_s, result.landmarks_final, result.euclidean_final,
      result.landmarks_created, timing.median, timing.p90, timing.max, ate, ate_pct, ev.path_length_m,
      ev.sim3_scale, ro.out);
}

// The search's time budget of a run (search/time_budget_ms): --search-budget, else the config's, else with --realtime
// half the frame period at the replay speed, shared by the cameras — the other half is left to the robot prediction,
// landmark initialization, map management and the reading of the next image. Returns where it came from ("off" when
// none).
std::string run_search_budget(const RunOptions& ro, std::optional<double> realtime_speed, const io::Dataset& ds,
                              pipeline::ImageSlamOptions& o) {
  if (ro.search_budget_ms) return *ro.search_budget_ms > 0.0 ? "--search-budget" : "off";  // set before --dump-config
  if (o.search.time_budget_ms > 0.0) return "config";
  const double rate_hz = ds.rig.cameras.empty() ? 0.0 : ds.rig.cameras.front().rate_hz;
  if (!realtime_speed || !(rate_hz > 0.0)) return "off";
  const double cameras = static_cast<double>(std::max<std::size_t>(1, o.camera_indices().size()));
  o.search.time_budget_ms =
      std::min(0.5 * 1e3 / rate_hz / *realtime_speed / cameras, strategies::ActiveSearchOptions::kMaxTimeBudgetMs);
  return "--realtime";
}

// Monocular or inertial-monocular image SLAM on a dataset or the simulator (src/rtslam/pipeline/image_slam.hpp):
// camera 0 of the rig, the IMU when the configuration's robot is inertial. Without --config, simulated runs use the
// built-in config/sim_mono.yaml and dataset runs the options' defaults.
void run_dataset(const RunOptions& ro) {
  const bool simulated = ro.dataset.empty() || ro.dataset.rfind("sim:", 0) == 0;
  pipeline::ImageSlamOptions o = !ro.config.empty() ? pipeline::load_image_slam_config(ro.config)
                                 : simulated        ? pipeline::default_sim_options()
                                                    : pipeline::ImageSlamOptions{};
  if (!ro.dataset.empty() && simulated) o.sim_preset = ro.dataset.substr(4);
  if (ro.seed) o.seed = *ro.seed;
  if (ro.duration_s) {
    if (!simulated) throw ConfigError("--duration applies to simulated runs only (no --dataset, or sim:PRESET)");
    o.sim_duration_s = *ro.duration_s;
  }
  if (ro.search_budget_ms) o.search.time_budget_ms = *ro.search_budget_ms;
  if (ro.overlay_frame) {
    o.overlay_frame = *ro.overlay_frame;
    o.overlay_path = fmt::format("{}/overlay_{:05d}.png", ro.out, *ro.overlay_frame);
  }
  o.validate();
  if (ro.dump_config) {
    std::cout << YAML::Dump(pipeline::to_yaml(o)) << '\n';
    return;
  }
  if (ro.dataset.rfind("camera:", 0) == 0 && o.robot == "inertial" && ro.input.imu_stream.empty()) {
    throw ConfigError(fmt::format("{}: a live camera streams no IMU, which slam/robot: inertial needs: pair one with "
                                  "--imu-stream (docs/datasets.md, \"Live camera with an IMU\")",
                                  ro.dataset));
  }
  if (!ro.input.imu_stream.empty() && o.robot != "inertial") {
    throw ConfigError(fmt::format("--imu-stream {}: the configuration's robot is {}, which reads no IMU (slam/robot: "
                                  "inertial)",
                                  ro.input.imu_stream, o.robot));
  }
  prepare_out_dir(ro);          // an earlier run's outputs: refused, or removed with --force
  RunDisplays displays(ro, o);  // before the input: a port in use or a bad path fails at once
  io::DatasetOptions dopt = ro.input;
  dopt.use_imu = o.robot == "inertial";
  dopt.cameras = o.camera_indices();
  dopt.rate_hz = ro.rate_hz ? *ro.rate_hz : o.rate_hz;
  dopt.start_offset_s = ro.start_at_s;
  dopt.duration_s = ro.stop_after_s;
  io::Dataset ds = simulated ? pipeline::make_sim_dataset(o) : io::open_dataset(ro.dataset, dopt);
  if (simulated && (ro.start_at_s > 0.0 || ro.stop_after_s > 0.0)) {
    ds.source = std::make_unique<io::WindowSource>(std::move(ds.source), ro.start_at_s, ro.stop_after_s);
  }
  io::start_prefetch(ds.source, ro.prefetch);  // decoding (rendering) in worker threads; the stream is the same
  // Calibration check (inertial runs): a pre-pass over the dataset opened again; the run's stream timing recorded.
  std::string calibration_skipped;
  const auto calibration = calibration_prepass(ro.dataset, dopt, o, simulated, calibration_skipped, ro.prefetch);
  // Real time: the stream is released at the sensor clock by an acquisition thread; late images are dropped. A live
  // camera is always read so (its clock is the wall clock: speed 1, released as it arrives). A replay's clock starts
  // at the filter's first request, so the set-up below drops nothing.
  const bool live = ds.kind == "camera";
  const std::optional<double> realtime_speed = live ? std::optional<double>(1.0) : ro.realtime;
  io::RealtimeSource* realtime = nullptr;
  if (realtime_speed) {
    auto rt = std::make_unique<io::RealtimeSource>(std::move(ds.source), *realtime_speed,
                                                   io::RealtimeSource::kDefaultMaxQueue, live);
    rt->set_interrupt(&g_run_stop);  // Ctrl-C while the filter waits for a late (or never coming) measurement
    realtime = rt.get();
    ds.source = std::move(rt);
  }
  auto stream_monitor = std::make_unique<calib::StreamMonitor>(std::move(ds.source));
  const calib::StreamMonitor& run_stream = *stream_monitor;
  ds.source = std::move(stream_monitor);
  const std::string budget_source = run_search_budget(ro, realtime_speed, ds, o);
  if (!realtime_speed && o.search.time_budget_ms > 0.0) {
    logger("run")->warn("search budget {:.3g} ms ({}) on a run that is not real time: which landmarks are searched "
                        "depends on this machine's speed, so the result may differ from run to run",
                        o.search.time_budget_ms, budget_source);
  }
  io::write_config_yaml(ro.out + "/config.yaml", pipeline::to_yaml(o));
  displays.attach(ds, o.seed);

  const auto total = ds.source->image_count();
  io::ProgressLine progress(total ? *total : 0, nullptr, ro.quiet ? std::optional<bool>(false) : std::nullopt);
  // A dataset's Rig holds the selected cameras only (the simulator's holds all of its own).
  pipeline::ImageSlamOptions run_o = simulated ? o : o.on_selected_cameras();
  // trajectory.csv and frames.csv stream into their .tmp during the run (flushed every second: a killed run leaves
  // the rows so far there) and are renamed at its end.
  io::TrajectoryCsvWriter trajectory_csv(ro.out + "/trajectory.csv");
  io::FramesCsvWriter frames_csv(ro.out + "/frames.csv");
  const auto observer = [&](const pipeline::ImageSlamFrame& f) {
    trajectory_csv.write(*f.pose);
    frames_csv.write(to_io(*f.stats, o.camera_indices().front()));
    if (displays.active()) displays.on_frame(f);
  };
  RunSignals signals;
  pipeline::ImageSlamResult result;
  bool interrupted = false;
  nlohmann::json summary;
  std::string accuracy_line, display_line, calibration_line, realtime_line, budget_line, fallback_line, rest_line;
  std::string groundtruth_error;  // --groundtruth given and not usable: the run fails after writing its outputs
  std::vector<double> times;
  io::Percentiles timing;
  nlohmann::json stages;
  int min_matched = std::numeric_limits<int>::max(), min_matched_after_1s = std::numeric_limits<int>::max();
  try {
    result = pipeline::run_image_slam(
        ds, run_o, [&](int done, int) { progress.update(static_cast<size_t>(done)); }, observer, &g_run_stop);
    interrupted = g_run_stop.load();
    // The acquisition ends here (a run stopped early leaves it reading): the input's counts and the images left
    // untaken are final before they are reported, and a live camera is released during a --view hold.
    if (realtime != nullptr) realtime->stop();
    progress.finish();
    displays.finish_run();
    trajectory_csv.close();
    frames_csv.close();
    io::write_tum(ro.out + "/trajectory.txt", result.estimate);
    if (ds.ground_truth)
      io::write_tum(ro.out + "/groundtruth.txt", *ds.ground_truth);
    else if (!ro.groundtruth.empty())
      io::write_tum(ro.out + "/groundtruth.txt", io::read_trajectory(ro.groundtruth));
    {
      std::vector<io::MapPoint> pts;
      for (size_t i = 0; i < result.landmark_ids.size(); ++i) {
        io::MapPoint mp;
        mp.id = static_cast<std::uint64_t>(result.landmark_ids[i]);
        mp.p_W = result.landmark_positions[i];
        mp.cov = result.landmark_covariances[i];
        mp.euclidean = result.landmark_euclidean[i] != 0;
        pts.push_back(mp);
      }
      io::write_map_ply(ro.out + "/map.ply", pts);
    }
    times.reserve(result.frames.size());
    for (const auto& s : result.frames) times.push_back(s.time_total_ms);
    timing = io::percentiles(times);
    // Median of each stage (frames.csv has them per frame).
    const auto stage_median = [&](double slam::FrameStats::*field) {
      std::vector<double> v;
      v.reserve(result.frames.size());
      for (const auto& s : result.frames) v.push_back(s.*field);
      return io::percentiles(v).median;
    };
    stages = {{"predict", stage_median(&slam::FrameStats::time_predict_ms)},
              {"match", stage_median(&slam::FrameStats::time_match_ms)},
              {"ransac", stage_median(&slam::FrameStats::time_ransac_ms)},
              {"update", stage_median(&slam::FrameStats::time_update_ms)},
              {"init", stage_median(&slam::FrameStats::time_init_ms)},
              {"map", stage_median(&slam::FrameStats::time_map_ms)}};

    summary["status"] = interrupted ? "interrupted" : "complete";
    summary["mode"] = fmt::format("{}{} EKF-SLAM{}: active search, one-point RANSAC, AHP landmarks",
                                  result.inertial ? "inertial-" : "",
                                  result.cameras > 1 ? fmt::format("{}-camera", result.cameras) : "monocular",
                                  result.inertial ? " with IMU-driven prediction" : " on images");
    if (result.inertial) {
      const auto v3 = [](const Eigen::Vector3d& v) { return std::vector<double>{v.x(), v.y(), v.z()}; };
      summary["imu"] = {{"start", result.inertial_start},
                        {"samples", result.imu_samples},
                        {"samples_integrated", result.imu_samples_integrated},
                        {"gyro_saturated_samples", result.imu_gyro_saturated},
                        {"accel_saturated_samples", result.imu_accel_saturated},
                        {"images_before_start", result.images_before_start},
                        {"images_not_covered", result.images_not_covered},
                        {"gravity_W", v3(result.gravity_W)},
                        {"accel_bias", v3(result.accel_bias)},
                        {"gyro_bias", v3(result.gyro_bias)}};
      if (result.extrinsics_estimated) {
        const auto pose = [&](const math::Pose& T) {
          return nlohmann::json{{"p_RS", v3(T.p)}, {"q_RS_wxyz", {T.q.w(), T.q.x(), T.q.y(), T.q.z()}}};
        };
        const math::Pose d = result.T_RS_calibration.inverse() * result.T_RS_estimate;
        summary["imu"]["extrinsics"] = {
            {"calibration", pose(result.T_RS_calibration)},
            {"estimate", pose(result.T_RS_estimate)},
            {"std_p_m", v3(result.T_RS_std.head<3>())},
            {"std_theta_deg", v3(result.T_RS_std.tail<3>() * 180.0 / M_PI)},
            {"change_from_calibration",
             {{"p_m", (result.T_RS_estimate.p - result.T_RS_calibration.p).norm()},
              {"rotation_deg", d.q.angularDistance(Eigen::Quaterniond::Identity()) * 180.0 / M_PI}}}};
      }
      if (result.time_offset_estimated) {  // camera/time_offset: t_imu = t_cam + t_d
        summary["imu"]["time_offset"] = {{"stamped_ms", 1e3 * result.time_offset_stamped_s},
                                         {"estimate_ms", 1e3 * result.time_offset_estimate_s},
                                         {"std_ms", 1e3 * result.time_offset_std_s}};
      }
    }
    {
      long refused = 0, without_search = 0, with_fallback = 0, nis_n = 0, abs_updates = 0, abs_rejected = 0;
      long at_rest = 0;
      double nis_sum = 0.0;
      for (const auto& f : result.frames) {
        refused += f.refused;
        abs_updates += f.absolute_updates;
        abs_rejected += f.absolute_rejected;
        without_search += f.searched == 0 ? 1 : 0;
        with_fallback += f.fallback > 0 ? 1 : 0;
        at_rest += f.zero_velocity ? 1 : 0;
        nis_sum += f.nis;
        nis_n += f.nis_count;
      }
      if (with_fallback > 0) {
        fallback_line = fmt::format(
            "  search: in {} frame(s) too few search boxes fitted search/max_search_size_px2; the smallest larger "
            "ones were searched (search/min_candidates)\n",
            with_fallback);
      }
      summary["health"] = {{"final", slam::to_string(result.final_health)},
                           {"frames_lost", result.frames_lost},
                           {"frames_diverged", result.frames_diverged},
                           {"resets", result.resets},
                           {"image_gaps", result.frame_gaps},
                           {"frames_without_search", without_search},
                           {"frames_with_search_fallback", with_fallback},
                           {"corrections_refused", refused},
                           {"never_tracked", !pipeline::never_tracked(result).empty()},
                           {"mean_nis_per_dof", nis_n > 0 ? nis_sum / (2.0 * static_cast<double>(nis_n)) : 0.0}};
      if (o.position_sensor.enabled || o.pose_sensor.enabled) {
        summary["absolute"] = {{"corrections_applied", abs_updates}, {"corrections_rejected", abs_rejected}};
      }
      if (o.zero_velocity.enabled) {
        summary["zero_velocity"] = {{"frames_with_update", at_rest}};
        rest_line = fmt::format("  zero velocity: v = 0 fused after {} of {} frame(s) (zero_velocity)\n", at_rest,
                                result.frames.size());
      }
      if (o.robot == "odometry") {
        summary["odometry"] = {{"rescale", result.odometry_rescale},
                               {"rescales", result.odometry_rescales},
                               {"rescale_product", result.odometry_rescale_product}};
      }
    }
    summary["dataset"] = {{"name", ds.name}, {"kind", ds.kind}, {"path", ds.path}};
    if (!dopt.imu_stream.empty()) {
      summary["dataset"]["imu_stream"] = {
          {"path", dopt.imu_stream}, {"clock", dopt.imu_clock == io::ImuStreamClock::Host ? "host" : "device"}};
    }
    summary["input"] = ds.source->stats().to_json();
    if (realtime != nullptr) {
      const io::RealtimeStats rs = realtime->realtime();
      summary["realtime"] = {{"speed", *realtime_speed},
                             {"live", live},
                             {"images_released", rs.images_released},
                             {"images_processed", rs.images_taken},
                             {"images_dropped", rs.images_dropped},
                             {"images_left", rs.images_left},
                             {"imu_samples", rs.imu_samples},  // released, all of them (never dropped)
                             {"max_lag_s", rs.max_lag_s},
                             {"mean_lag_s", rs.mean_lag_s},
                             {"reader_late_s", rs.reader_late_s}};
      realtime_line = fmt::format(
          "  real time ({}x the sensor clock): {} of {} images processed, {} dropped (late){}; filter lag mean "
          "{:.1f} ms, max {:.1f} ms; acquisition late by up to {:.1f} ms\n",
          *realtime_speed, rs.images_taken, rs.images_released, rs.images_dropped,
          rs.images_left > 0 ? fmt::format(", {} left when the run stopped", rs.images_left) : std::string(),
          1e3 * rs.mean_lag_s, 1e3 * rs.max_lag_s, 1e3 * rs.reader_late_s);
      if (rs.images_dropped > 0) {
        logger("run")->warn("real time: {} image(s) dropped because the filter was busy (speed {}x)", rs.images_dropped,
                            *realtime_speed);
      }
      // The input itself slower than the clock (reading and decoding, or a consumer behind on IMU samples): the replay
      // was not at the requested speed, whatever the filter did. A tenth of a second is beyond scheduling noise.
      if (rs.reader_late_s > 0.1) {
        logger("run")->warn(
            "real time: the input fell behind the sensor clock by up to {:.2f} s (reading, decoding and "
            "feeding the filter slower than {}x): this replay ran slower than requested",
            rs.reader_late_s, *realtime_speed);
      }
    }
    {
      // The search's time budget: frames where it ran out, landmarks it left unsearched, the search's time.
      long frames_hit = 0, skipped = 0;
      std::vector<double> search_ms;
      search_ms.reserve(result.frames.size());
      for (const auto& f : result.frames) {
        frames_hit += f.budget_hit ? 1 : 0;
        skipped += f.budget_skipped;
        search_ms.push_back(f.time_search_ms);
      }
      const io::Percentiles sp = io::percentiles(search_ms);
      summary["search_budget"] = {{"budget_ms", o.search.time_budget_ms},
                                  {"source", budget_source},
                                  {"frames_hit", frames_hit},
                                  {"landmarks_skipped", skipped},
                                  {"search_ms", io::to_json(sp)}};
      if (o.search.time_budget_ms > 0.0) {
        budget_line = fmt::format(
            "  search budget {:.3g} ms ({}): ran out in {} of {} frames, {} landmarks left unsearched; search time "
            "median {:.3f} ms, max {:.3f} ms\n",
            o.search.time_budget_ms, budget_source, frames_hit, result.frames.size(), skipped, sp.median, sp.max);
      }
    }
    calibration_line = calibration_summary(calibration, calibration_skipped, run_stream.report(), summary);
    summary["seed"] = o.seed;
    summary["frames"] = result.frames.size();
    summary["landmarks"] = {{"final", result.landmarks_final},
                            {"created", result.landmarks_created},
                            {"euclidean_final", result.euclidean_final}};
    summary["timing_ms"] = io::to_json(timing);
    summary["timing_stage_median_ms"] = stages;
    // Matched landmarks per frame, over every frame and after the first second (the map is being built then).
    for (const auto& s : result.frames) {
      min_matched = std::min(min_matched, s.matched);
      if (!result.frames.empty() && s.t - result.frames.front().t >= 1'000'000'000) {
        min_matched_after_1s = std::min(min_matched_after_1s, s.matched);
      }
    }
    if (!result.frames.empty()) {
      summary["matched_min"] = min_matched;
      if (min_matched_after_1s != std::numeric_limits<int>::max())
        summary["matched_min_after_1s"] = min_matched_after_1s;
    }
    // Accuracy, when a reference is at hand (--groundtruth, or the dataset's own): evaluation only, after the run.
    std::optional<Trajectory> reference;
    if (!ro.groundtruth.empty()) {
      reference = io::read_trajectory(ro.groundtruth);
    } else if (ds.ground_truth) {
      reference = std::move(ds.ground_truth);
    }
    if (reference && result.estimate.poses.size() >= 3) {
      try {
        // Metric scale (SE(3) ATE and the scale error): an IMU or a stereo baseline; monocular: Sim(3).
        const eval::RunAccuracy acc =
            eval::evaluate_accuracy(result.estimate, *reference, result.inertial || result.cameras > 1);
        summary["accuracy"] = acc.json;
        summary["accuracy"]["reference"] = ro.groundtruth.empty() ? std::string("dataset") : ro.groundtruth;
        summary["ate_percent_of_path"] = acc.json["ate_percent_of_path"];
        accuracy_line = acc.line;
      } catch (const Error& e) {
        summary["accuracy_error"] = e.what();
        accuracy_line = fmt::format("  ATE not computed: {}\n", e.what());
        if (!ro.groundtruth.empty()) groundtruth_error = e.what();
      }
    }
    display_line = displays.report_line(summary);
    io::write_summary_json(ro.out + "/summary.json", summary);
  } catch (const std::exception& e) {
    // A failed (or, before its first image, interrupted) run: what is safe stays — config.yaml, and trajectory.csv
    // and frames.csv with the rows written so far (unless the error was theirs: then they are gone) — and summary.json
    // says why.
    progress.finish();
    for (const auto& close :
         std::initializer_list<std::function<void()>>{[&] { trajectory_csv.close(); }, [&] { frames_csv.close(); }}) {
      try {
        close();
      } catch (const std::exception&) {
      }
    }
    const int sig = RunSignals::received();
    nlohmann::json failed = {{"status", sig ? "interrupted" : "failed"},
                             {"error", e.what()},
                             {"dataset", {{"name", ds.name}, {"kind", ds.kind}, {"path", ds.path}}},
                             {"seed", o.seed},
                             {"frames", trajectory_csv.rows()}};
    try {
      io::write_summary_json(ro.out + "/summary.json", failed);
    } catch (const std::exception&) {
    }
    if (sig) {
      std::cerr << fmt::format("rtslam: interrupted by {} ({}); outputs in {}/\n", signal_name(sig), e.what(), ro.out);
      throw CommandExit{128 + sig};
    }
    throw;
  }
  signals.restore();
  if (ro.overlay_frame && !std::filesystem::exists(o.overlay_path)) {
    logger("run")->warn("--overlay-frame {}: no overlay written, the filter processed {} frame(s)", *ro.overlay_frame,
                        result.frames.size());
  }
  std::cout << fmt::format(
      "rtslam run on {} ({}), seed {}: {} frames\n"
      "  landmarks: {} in map at the end ({} Euclidean), {} created; matched per frame: min {} ({} after 1 s)\n"
      "  per-frame time: median {:.3f} ms, p90 {:.3f} ms, max {:.3f} ms (stage medians: predict {:.3f}, match "
      "{:.3f}, ransac {:.3f}, update {:.3f}, init {:.3f}, map {:.3f})\n"
      "{}{}{}{}{}  outputs in {}/\n",
      ds.name, ds.kind, o.seed, result.frames.size(), result.landmarks_final, result.euclidean_final,
      result.landmarks_created, result.frames.empty() ? 0 : min_matched,
      min_matched_after_1s == std::numeric_limits<int>::max() ? 0 : min_matched_after_1s, timing.median, timing.p90,
      timing.max, stages["predict"].get<double>(), stages["match"].get<double>(), stages["ransac"].get<double>(),
      stages["update"].get<double>(), stages["init"].get<double>(), stages["map"].get<double>(), accuracy_line,
      (result.resets > 0 || result.frames_lost + result.frames_diverged > 0
           ? fmt::format("  health: {} frame(s) lost, {} diverged, {} re-initialization(s); last frame {}\n",
                         result.frames_lost, result.frames_diverged, result.resets,
                         slam::to_string(result.final_health))
           : std::string()) +
          (result.inertial
               ? fmt::format("  IMU: {}; {} samples, {} gyro / {} accel saturated; {} images before the start\n",
                             result.inertial_start, result.imu_samples, result.imu_gyro_saturated,
                             result.imu_accel_saturated, result.images_before_start)
               : std::string()) +
          (result.odometry_rescale
               ? fmt::format("  odometry: the map's scale kept at the odometry's (odometry/rescale): {} rescale(s), "
                             "factor {:.4f} in all\n",
                             result.odometry_rescales, result.odometry_rescale_product)
               : std::string()),
      calibration_line, realtime_line + budget_line + fallback_line + rest_line, display_line, ro.out);
  std::cout << std::flush;
  if (const int sig = RunSignals::received()) {
    std::cerr << fmt::format(
        "rtslam: interrupted by {} after {} frame(s); outputs of what was processed in {}/ "
        "(summary.json status {})\n",
        signal_name(sig), result.frames.size(), ro.out, interrupted ? "interrupted" : "complete");
    throw CommandExit{128 + sig};
  }
  displays.hold(ro);
  if (result.final_health != slam::Health::Ok) {
    throw DataError(fmt::format("the run ended with tracking {} ({} re-initialization(s) did not recover it); outputs "
                                "in {}/ describe a broken estimate", slam::to_string(result.final_health),
                                result.resets, ro.out));
  }
  if (const std::string why = pipeline::never_tracked(result); !why.empty()) {
    throw DataError(fmt::format("{}; outputs in {}/", why, ro.out));
  }
  if (!groundtruth_error.empty()) {
    throw DataError(fmt::format("--groundtruth {}: no accuracy report ({}); the run's outputs are in {}/",
                                ro.groundtruth, groundtruth_error, ro.out));
  }
}

}  // namespace

void register_run(CLI::App& app) {
  auto opts = std::make_shared<RunOptions>();
  auto* sub = app.add_subcommand("run", "Run SLAM on a dataset, or on the built-in simulated demo (no --dataset)");
  sub->add_option("--dataset", opts->dataset,
                  "KIND:PATH of a dataset (euroc, tum, kitti, images, video), camera:N for the live camera /dev/videoN "
                  "(with --calibration; camera:FILE: a video played in a loop standing in for one; ends with "
                  "--stop-after or Ctrl-C), or sim:PRESET|FILE for the simulator; without it: the simulator's config "
                  "simulation/preset (default handheld)");
  sub->add_option("--config", opts->config, "YAML configuration (see docs/demo.md); an output folder's "
                                            "config.yaml reproduces its run");
  sub->add_flag("--dump-config", opts->dump_config, "Print the effective configuration and exit");
  sub->add_option("--out", opts->out, "Output folder")->capture_default_str();
  sub->add_option("--seed", opts->seed, "Seed of every random draw of the run (overrides the config; default 1)");
  sub->add_option("--duration", opts->duration_s, "Simulated runs: duration in s (default: the preset's, 30)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--rate", opts->rate_hz,
                  "Image folders: their rate in Hz; videos: frames at i / rate instead of their own times; "
                  "--points-demo: camera rate (default 30)")
      ->check(CLI::PositiveNumber);
  sub->add_flag("--points-demo", opts->points_demo,
                "Run the walking skeleton instead: simulated point measurements with known association");
  sub->add_option("--points", opts->points, "--points-demo: number of 3D points in the room (default 500)")
      ->check(CLI::Range(10, 100000));
  sub->add_option("--overlay-frame", opts->overlay_frame,
                  "Write OUT/overlay_NNNNN.png of this image (0-based): the --overlays drawing of one frame "
                  "(slam/overlay_frame)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--view", opts->view,
                  "Serve the live web viewer on ADDR:PORT or PORT while the run goes (default 127.0.0.1:0: "
                  "loopback, a free port; the URL is printed). The run waits for a browser only with --view-wait; afterwards "
                  "the viewer keeps serving until Ctrl-C (see --view-hold). docs/viewer.md")
      ->expected(0, 1)
      ->type_name("[ADDR:PORT]");
  sub->add_option("--view-wait", opts->view_wait_s,
                  "--view: before the run, wait up to this many seconds for a browser to connect (default 0: "
                  "start at once)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--view-hold", opts->view_hold_s,
                  "--view: after the run, keep serving this many seconds (0: stop at once; default: until Ctrl-C)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--overlays", opts->overlays,
                  "Write one overlay PNG per processed frame (search ellipses, matches, new landmarks, init grid) "
                  "and index.csv into DIR (default OUT/overlays, which rtslam view OUT shows)")
      ->expected(0, 1)
      ->type_name("[DIR]");
  sub->add_option("--overlay-every", opts->overlay_every, "--overlays: write every Nth frame only")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  sub->add_option("--video", opts->video,
                  "Write the overlays of every frame as a video: .avi/.mkv (MJPG), .mp4/.m4v/.mov (H.264, else "
                  "MPEG-4), .webm (VP8)")
      ->type_name("FILE");
  sub->add_option("--groundtruth", opts->groundtruth,
                  "Reference trajectory (TUM, EuRoC state CSV, KITTI) for the accuracy report after the run; the "
                  "estimator never reads it")
      ->check(CLI::ExistingFile);
  sub->add_option("--start-at", opts->start_at_s,
                  "Start this many seconds after the first measurement of the input (data before is skipped)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--stop-after", opts->stop_after_s, "Process this many seconds of input from the start (0: all)")
      ->check(CLI::NonNegativeNumber);
  sub->add_option_function<std::string>(
         "--realtime",
         [opts](const std::string& v) {
           double speed = 1.0;
           if (!v.empty()) {
             std::size_t used = 0;
             try {
               speed = std::stod(v, &used);
             } catch (const std::exception&) {
               used = 0;
             }
             if (used != v.size() ||
                 !(speed >= io::RealtimeSource::kMinSpeed && speed <= io::RealtimeSource::kMaxSpeed)) {
               throw ConfigError(fmt::format("--realtime = '{}' must be a speed in [{}, {}]", v,
                                             io::RealtimeSource::kMinSpeed, io::RealtimeSource::kMaxSpeed));
             }
           }
           opts->realtime = speed;
         },
                  "Replay the input at its sensor clock times SPEED (default 1), as live data: an acquisition thread "
                  "reads ahead, the filter takes the newest image and late images are dropped and counted (the IMU "
                  "never); summary.json 'realtime'")
      ->expected(0, 1)
      ->type_name("[SPEED]");
  sub->add_option("--search-budget", opts->search_budget_ms,
                  "The active search's time budget per frame in ms (search/time_budget_ms; 0: off): the search stops "
                  "matching new landmarks when it is spent and corrects with what it matched. Default: the config's; "
                  "with --realtime and none configured, half the frame period at the replay speed")
      ->check(CLI::Range(0.0, strategies::ActiveSearchOptions::kMaxTimeBudgetMs));
  // The input options of io::DatasetOptions (docs/datasets.md, docs/ros.md); --rate, --start-at and --stop-after above.
  sub->add_option_function<std::string>(
         "--bad-input",
         [opts](const std::string& v) { opts->input.bad_input = io::bad_input_policy_from_string(v, "--bad-input"); },
         "Bad input (timestamps out of order, duplicates, NaN, IMU samples beyond the sensor's range, malformed "
         "lines, missing or undecodable images): error (default: stop with one line naming the file) or skip (drop "
         "it, count it in summary.json input/*, warn)")
      ->type_name("error|skip")
      ->check(CLI::IsMember({"error", "skip"}));
  sub->add_option("--calibration", opts->input.calibration,
                  "Calibration file overriding the dataset's own (EuRoC sensor.yaml, Kalibr camchain.yaml, rtslam rig "
                  "YAML, MonoSLAM camera.json; for bags also an EuRoC folder)")
      ->check(CLI::ExistingPath);
  sub->add_option("--timestamps", opts->input.timestamps,
                  "Image folders: timestamps file (one time in s per line, or 'time filename' lines) instead of "
                  "times.txt / timestamps.txt")
      ->check(CLI::ExistingFile);
  sub->add_option("--max-imu-dropout", opts->input.max_imu_dropout,
                  "More missing IMU samples than this in a row are an IMU gap (reported; an error unless --bad-input "
                  "skip)")
      ->capture_default_str()
      ->check(CLI::Range(0, io::DatasetOptions::kMaxImuDropout));
  sub->add_option_function<std::string>(
         "--image-topic", [opts](const std::string& v) { opts->input.image_topics = {v}; },
         "ROS bags: the camera's image topic (default /camN/image_raw, N = slam/camera)")
      ->type_name("TOPIC");
  sub->add_option("--imu-topic", opts->input.imu_topic, "ROS bags: the IMU topic (empty: none)")
      ->capture_default_str();
  sub->add_flag("--bag-receive-time", opts->input.bag_receive_time,
                "ROS bags: stamp measurements with the bag's receive times instead of the header stamps");
  sub->add_option("--imu-stream", opts->input.imu_stream,
                  "camera: inputs: a live IMU paired with the camera, as text lines 't[ns],w_x,w_y,w_z,a_x,a_y,a_z' "
                  "from a FIFO, a serial device, a file or - (standard input); needs an inertial configuration and a "
                  "calibration with the IMU (docs/datasets.md)");
  sub->add_option_function<std::string>(
         "--imu-clock",
         [opts](const std::string& s) { opts->input.imu_clock = io::imu_stream_clock_from_string(s, "--imu-clock"); },
         "--imu-stream: the clock of its times: host (this machine's CLOCK_MONOTONIC, default) or device (the IMU's "
         "own clock, mapped onto the host's by the smallest delivery delay)");
  sub->add_flag("--quiet", opts->quiet, "No progress line");
  add_prefetch_options(*sub, opts->prefetch);
  sub->add_flag("--force", opts->force,
                "Replace the outputs of an earlier run in --out (exactly rtslam's files: config.yaml, trajectory.*, "
                "groundtruth.txt, frames.csv, map.ply, summary.json, overlays/, overlay_*.png, the --video file "
                "there; other files stay). Without it such a folder is refused");
  sub->callback([opts, sub] {
    // The input options act on datasets only: on the simulator (or the points demo) they would be ignored silently.
    if (opts->dataset.empty() || opts->dataset.rfind("sim:", 0) == 0) {
      for (const char* flag : {"--bad-input", "--calibration", "--timestamps", "--max-imu-dropout", "--image-topic",
                               "--imu-topic", "--bag-receive-time", "--imu-stream", "--imu-clock"}) {
        if (sub->count(flag) > 0) {
          throw ConfigError(fmt::format("{} applies to --dataset runs (not the simulator or --points-demo)", flag));
        }
      }
    }
    if (opts->points_demo) {
      if (!opts->dataset.empty()) throw ConfigError("--points-demo and --dataset exclude each other");
      if (opts->view || opts->overlays || !opts->video.empty() || opts->overlay_frame) {
        throw ConfigError("--view, --overlays, --video and --overlay-frame show image runs: not --points-demo");
      }
      run_demo(*opts);
      return;
    }
    if (opts->points) throw ConfigError("--points applies to --points-demo only");
    if (opts->dataset.rfind("camera:", 0) == 0 && opts->realtime && *opts->realtime != 1.0) {
      throw ConfigError(fmt::format("--realtime {}: a live camera runs at its own clock (speed 1)", *opts->realtime));
    }
    if (sub->count("--imu-clock") > 0 && opts->input.imu_stream.empty()) {
      throw ConfigError("--imu-clock applies to --imu-stream only");
    }
    if (opts->view_hold_s && !opts->view) throw ConfigError("--view-hold applies to --view only");
    if (opts->overlay_every != 1 && !opts->overlays) throw ConfigError("--overlay-every applies to --overlays only");
    run_dataset(*opts);
  });
}

}  // namespace rtslam::cli
