// rtslam bench: the end-to-end per-frame benchmark. Runs the built-in demo (or a config of it) for several seeds
// in this process and reports per-frame processing time as medians and percentiles over all frames, per stage,
// and as a ratio to the paper's 60 Hz budget. Micro-benchmarks of single routines are in bench/ (Google Benchmark).
// `rtslam bench --pipeline` does the same for the image pipeline on a dataset (or the simulator preset of the
// config), images decoded ahead (--prefetch), and adds the whole-run throughput (docs/performance.md).
#include <algorithm>
#include <time.h>
#include <chrono>
#include <ctime>
#include <fstream>
#include <iostream>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "prefetch_option.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/filter/kernels.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/writers.hpp"
#include "rtslam/pipeline/demo_config.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/pipeline/point_demo.hpp"
#include "rtslam/sim/point_scene.hpp"

namespace rtslam::cli {
namespace {

struct BenchOptions {
  std::string config;
  int seeds = 3;
  std::optional<double> duration_s;  // demo: 30 s; --pipeline: the simulator preset's
  std::string json;
  bool pipeline = false;
  std::string dataset;
  int prefetch = -1;
  bool quiet = false;
};

/// A pass-through source that adds up the time its consumer spent in next(): decoding without prefetch, waiting
/// for the decoding threads with it.
class BenchTimedSource final : public io::Source {
 public:
  explicit BenchTimedSource(std::unique_ptr<io::Source> inner) : inner_(std::move(inner)) {}
  std::optional<io::Measurement> next() override {
    const auto t0 = std::chrono::steady_clock::now();
    auto m = inner_->next();
    in_next_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return m;
  }
  const io::SourceStats& stats() const override { return inner_->stats(); }
  std::optional<std::size_t> image_count() const override { return inner_->image_count(); }
  bool seek(TimeNs t) override { return inner_->seek(t); }
  double in_next_s = 0.0;

 private:
  std::unique_ptr<io::Source> inner_;
};

/// The 1-minute load average (/proc/loadavg), -1 where unknown: figures from a loaded machine say so.
double bench_load_average() {
  std::ifstream in("/proc/loadavg");
  double load = -1.0;
  in >> load;
  return load;
}

void run_pipeline_bench(const BenchOptions& bo) {
  pipeline::ImageSlamOptions o =
      bo.config.empty() ? pipeline::ImageSlamOptions{} : pipeline::load_image_slam_config(bo.config);
  const bool simulated = bo.dataset.empty();
  if (bo.duration_s) {
    if (!simulated) throw ConfigError("--duration applies to simulated runs (--pipeline without --dataset)");
    o.sim_duration_s = *bo.duration_s;
  }
  o.validate();
  io::DatasetOptions dopt;  // as `rtslam run` opens it
  dopt.use_imu = o.robot == "inertial";
  dopt.cameras = {o.camera};
  dopt.rate_hz = o.rate_hz;
  io::Dataset ds = simulated ? pipeline::make_sim_dataset(o) : io::open_dataset(bo.dataset, dopt);
  const int threads = io::start_prefetch(ds.source, bo.prefetch);
  auto timed = std::make_unique<BenchTimedSource>(std::move(ds.source));
  BenchTimedSource& source = *timed;
  ds.source = std::move(timed);
  pipeline::ImageSlamOptions run_o = o;
  run_o.camera = 0;  // the Rig holds the selected camera only
  const auto total = ds.source->image_count();
  io::ProgressLine progress(total ? *total : 0, nullptr, bo.quiet ? std::optional<bool>(false) : std::nullopt);
  const double load_before = bench_load_average();
  const std::clock_t cpu0 = std::clock();
  timespec thread0{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &thread0);
  const auto t0 = std::chrono::steady_clock::now();
  // The filter thread's CPU time between two processed images: what a frame costs the estimator whatever else
  // runs on the machine (the wall-clock stage timings count the time the thread waited for a core too).
  std::vector<std::pair<TimeNs, double>> frame_cpu_ms;
  frame_cpu_ms.reserve(total ? *total : 4096);
  timespec cpu_prev = thread0;
  const auto result = pipeline::run_image_slam(
      ds, run_o, [&](int done, int) { progress.update(static_cast<size_t>(done)); },
      [&](const pipeline::ImageSlamFrame& f) {
        timespec now{};
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
        frame_cpu_ms.emplace_back(f.t, 1e3 * static_cast<double>(now.tv_sec - cpu_prev.tv_sec) +
                                           1e-6 * static_cast<double>(now.tv_nsec - cpu_prev.tv_nsec));
        cpu_prev = now;
      });
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const double cpu_s = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC;
  timespec thread1{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &thread1);
  const double filter_cpu_s = static_cast<double>(thread1.tv_sec - thread0.tv_sec) +
                              1e-9 * static_cast<double>(thread1.tv_nsec - thread0.tv_nsec);
  progress.finish();
  const double load_after = bench_load_average();

  std::vector<double> total_ms, predict, match, ransac, update, init, map, corrections, hypotheses;
  double filter_s = 0.0;
  const TimeNs t_first = result.frames.empty() ? 0 : result.frames.front().t;
  for (const auto& f : result.frames) {
    filter_s += f.time_total_ms * 1e-3;
    if (f.t < t_first + from_seconds(1.0)) continue;  // the first second: the start, the map filling
    total_ms.push_back(f.time_total_ms);
    predict.push_back(f.time_predict_ms);
    match.push_back(f.time_match_ms);
    ransac.push_back(f.time_ransac_ms);
    update.push_back(f.time_update_ms);
    init.push_back(f.time_init_ms);
    map.push_back(f.time_map_ms);
    corrections.push_back(f.updated);
    hypotheses.push_back(f.ransac_hypotheses);
  }
  const auto t = io::percentiles(total_ms);
  const auto corr = io::percentiles(corrections);
  const double at_least_20 =
      corrections.empty() ? 0.0
                          : static_cast<double>(std::count_if(corrections.begin(), corrections.end(),
                                                              [](double n) { return n >= 20.0; })) /
                                static_cast<double>(corrections.size());
  std::vector<double> cpu_ms;
  for (const auto& [tf, ms] : frame_cpu_ms) {
    if (tf >= t_first + from_seconds(1.0)) cpu_ms.push_back(ms);
  }
  const auto c = io::percentiles(cpu_ms);
  const auto images = ds.source->stats().images;
  const double fps = static_cast<double>(images) / std::max(wall_s, 1e-9);
  std::cout << fmt::format(
      "rtslam bench --pipeline: {} ({}), {} images, {} processed by the filter, {} timed "
      "(first second excluded)\n",
      ds.name, simulated ? "simulated, rendered on the fly" : ds.kind, images, result.frames.size(), t.count);
  std::cout << fmt::format("  per-frame total: median {:.3f} ms, p90 {:.3f} ms, p99 {:.3f} ms, max {:.3f} ms\n",
                           t.median, t.p90, t.p99, t.max);
  std::cout << fmt::format(
      "  per-frame filter-thread CPU (between processed images, IMU feeding included): median {:.3f} ms, p90 "
      "{:.3f} ms, p99 {:.3f} ms, max {:.3f} ms\n",
      c.median, c.p90, c.p99, c.max);
  std::cout << fmt::format(
      "  stages (median ms): predict {:.3f}, match {:.3f}, ransac {:.3f}, update {:.3f}, "
      "init {:.3f}, map {:.3f}\n",
      io::percentiles(predict).median, io::percentiles(match).median, io::percentiles(ransac).median,
      io::percentiles(update).median, io::percentiles(init).median, io::percentiles(map).median);
  std::cout << fmt::format("  corrections per frame (landmarks updated): median {:.0f}, mean {:.1f}, {:.1f} % of frames "
                           "with 20 or more\n",
                           corr.median, corr.mean, 100.0 * at_least_20);
  const auto hyp = io::percentiles(hypotheses);
  std::cout << fmt::format("  one-point RANSAC hypotheses per frame: median {:.0f}, mean {:.2f}, max {:.0f}\n", hyp.median,
                           hyp.mean, hyp.max);
  std::cout << fmt::format(
      "  throughput: {:.1f} images/s over {:.2f} s wall ({}), filter {:.2f} s, waiting for "
      "input {:.2f} s, process CPU {:.2f} s, load average {:.2f} -> {:.2f} on {} cores\n",
      fps, wall_s, threads > 0 ? fmt::format("prefetch: {} thread{}", threads, threads == 1 ? "" : "s") : "no prefetch",
      filter_s, source.in_next_s, cpu_s, load_before, load_after, std::thread::hardware_concurrency());
  // What the machine gives unloaded: the filter thread cannot go faster than its own CPU time, and the whole work
  // cannot go faster than the process CPU time spread over the cores.
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  const double bound_s = std::max(filter_cpu_s, cpu_s / cores);
  std::cout << fmt::format(
      "  CPU: filter thread {:.2f} s, other threads (decoding) {:.2f} s: on {} idle cores at "
      "most {:.0f} images/s; filter kernels {} (RTSLAM_KERNEL_ISA)\n",
      filter_cpu_s, std::max(0.0, cpu_s - filter_cpu_s), cores, static_cast<double>(images) / std::max(bound_s, 1e-9),
      filter::to_string(filter::kernel_isa()));
  if (!bo.json.empty()) {
    nlohmann::json j;
    j["dataset"] = ds.name;
    j["images"] = images;
    j["frames"] = t.count;
    j["total_ms"] = io::to_json(t);
    j["filter_thread_cpu_ms"] = io::to_json(c);
    j["predict_ms"] = io::to_json(io::percentiles(predict));
    j["match_ms"] = io::to_json(io::percentiles(match));
    j["ransac_ms"] = io::to_json(io::percentiles(ransac));
    j["update_ms"] = io::to_json(io::percentiles(update));
    j["init_ms"] = io::to_json(io::percentiles(init));
    j["map_ms"] = io::to_json(io::percentiles(map));
    j["corrections_per_frame"] = io::to_json(corr);
    j["frames_with_20_corrections"] = at_least_20;
    j["ransac_hypotheses_mean"] = hyp.mean;
    j["throughput_fps"] = fps;
    j["wall_s"] = wall_s;
    j["filter_s"] = filter_s;
    j["input_wait_s"] = source.in_next_s;
    j["cpu_s"] = cpu_s;
    j["filter_thread_cpu_s"] = filter_cpu_s;
    j["kernel_isa"] = filter::to_string(filter::kernel_isa());
    j["prefetch_threads"] = threads;
    j["load_average"] = {load_before, load_after};
    io::write_summary_json(bo.json, j);
  }
}

void run_bench(const BenchOptions& bo) {
  pipeline::PointDemoOptions o =
      bo.config.empty() ? pipeline::PointDemoOptions{} : pipeline::load_demo_config(bo.config);
  o.duration_s = bo.duration_s.value_or(30.0);
  std::vector<double> total;
  std::vector<double> predict;
  std::vector<double> update;
  std::vector<double> init;
  std::vector<double> map;
  for (int s = 0; s < bo.seeds; ++s) {
    o.seed = static_cast<std::uint64_t>(s + 1);
    sim::PointScene scene(o.scene());
    const auto r = pipeline::run_point_demo(o, scene);
    // The first second is warm-up (map filling, first allocations); it is excluded.
    for (size_t k = static_cast<size_t>(o.rate_hz); k < r.frames.size(); ++k) {
      const auto& f = r.frames[k];
      total.push_back(f.time_total_ms);
      predict.push_back(f.time_predict_ms);
      update.push_back(f.time_update_ms);
      init.push_back(f.time_init_ms);
      map.push_back(f.time_map_ms);
    }
  }
  const auto t = io::percentiles(total);
  std::cout << fmt::format("rtslam bench: demo, {} seeds x {:.0f} s, {} frames timed (first second excluded)\n",
                           bo.seeds, o.duration_s, t.count);
  std::cout << fmt::format("  per-frame total: median {:.3f} ms, p90 {:.3f} ms, p99 {:.3f} ms, max {:.3f} ms\n",
                           t.median, t.p90, t.p99, t.max);
  std::cout << fmt::format("  stages (median ms): predict {:.3f}, update {:.3f}, init {:.3f}, map {:.3f}\n",
                           io::percentiles(predict).median, io::percentiles(update).median,
                           io::percentiles(init).median, io::percentiles(map).median);
  std::cout << fmt::format("  ratio to the paper's 60 Hz budget (16.7 ms): {:.1f}x faster (median); filter kernels {} "
                           "(RTSLAM_KERNEL_ISA)\n",
                           (1000.0 / 60.0) / std::max(t.median, 1e-9), filter::to_string(filter::kernel_isa()));
  if (!bo.json.empty()) {
    nlohmann::json j;
    j["kernel_isa"] = filter::to_string(filter::kernel_isa());
    j["frames"] = t.count;
    j["total_ms"] = io::to_json(t);
    j["predict_ms"] = io::to_json(io::percentiles(predict));
    j["update_ms"] = io::to_json(io::percentiles(update));
    j["init_ms"] = io::to_json(io::percentiles(init));
    j["map_ms"] = io::to_json(io::percentiles(map));
    io::write_summary_json(bo.json, j);
  }
}

}  // namespace

void register_bench(CLI::App& app) {
  auto opts = std::make_shared<BenchOptions>();
  auto* sub = app.add_subcommand("bench",
                                 "Run the end-to-end per-frame benchmark (the built-in demo, or with "
                                 "--pipeline the image pipeline)");
  sub->add_option("--config", opts->config,
                  "Demo configuration (YAML) to benchmark; with --pipeline, an image "
                  "SLAM configuration (as rtslam run --config)");
  sub->add_flag("--pipeline", opts->pipeline,
                "Time the image pipeline on --dataset (or the simulator preset of --config) instead of the demo");
  sub->add_option("--dataset", opts->dataset, "--pipeline: dataset (as rtslam run --dataset; default: simulated)");
  add_prefetch_options(*sub, opts->prefetch);
  sub->add_flag("--quiet", opts->quiet, "--pipeline: no progress line");
  sub->add_option("--seeds", opts->seeds, "Runs (seeds 1..N)")->capture_default_str()->check(CLI::Range(1, 1000));
  sub->add_option("--duration", opts->duration_s,
                  "Seconds per run (default 30; --pipeline: of the simulated sequence, default the preset's)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--json", opts->json, "Also write the figures as JSON");
  sub->callback([opts] {
    if (opts->pipeline) {
      run_pipeline_bench(*opts);
      return;
    }
    if (!opts->dataset.empty()) throw ConfigError("--dataset applies to --pipeline only");
    run_bench(*opts);
  });
}

}  // namespace rtslam::cli
