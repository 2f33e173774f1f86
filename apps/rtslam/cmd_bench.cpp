// rtslam bench: the end-to-end per-frame benchmark. Runs the built-in demo (or a config of it) for several seeds
// in this process and reports per-frame processing time as medians and percentiles over all frames, per stage,
// and as a ratio to the paper's 60 Hz budget. Micro-benchmarks of single routines are in bench/ (Google Benchmark).
#include <iostream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "rtslam/io/writers.hpp"
#include "rtslam/pipeline/demo_config.hpp"
#include "rtslam/pipeline/point_demo.hpp"

namespace rtslam::cli {
namespace {

struct BenchOptions {
  std::string config;
  int seeds = 3;
  double duration_s = 30.0;
  std::string json;
};

void run_bench(const BenchOptions& bo) {
  pipeline::PointDemoOptions o = bo.config.empty() ? pipeline::PointDemoOptions{} : pipeline::load_demo_config(bo.config);
  o.duration_s = bo.duration_s;
  std::vector<double> total;
  std::vector<double> predict;
  std::vector<double> update;
  std::vector<double> init;
  std::vector<double> map;
  for (int s = 0; s < bo.seeds; ++s) {
    o.seed = static_cast<std::uint64_t>(s + 1);
    const auto r = pipeline::run_point_demo(o);
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
                           bo.seeds, bo.duration_s, t.count);
  std::cout << fmt::format("  per-frame total: median {:.3f} ms, p90 {:.3f} ms, p99 {:.3f} ms, max {:.3f} ms\n",
                           t.median, t.p90, t.p99, t.max);
  std::cout << fmt::format("  stages (median ms): predict {:.3f}, update {:.3f}, init {:.3f}, map {:.3f}\n",
                           io::percentiles(predict).median, io::percentiles(update).median,
                           io::percentiles(init).median, io::percentiles(map).median);
  std::cout << fmt::format("  ratio to the paper's 60 Hz budget (16.7 ms): {:.1f}x faster (median)\n",
                           (1000.0 / 60.0) / std::max(t.median, 1e-9));
  if (!bo.json.empty()) {
    nlohmann::json j;
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
  auto* sub = app.add_subcommand("bench", "Run the end-to-end per-frame benchmark (the built-in demo)");
  sub->add_option("--config", opts->config, "Demo configuration (YAML) to benchmark");
  sub->add_option("--seeds", opts->seeds, "Runs (seeds 1..N)")->capture_default_str()->check(CLI::Range(1, 1000));
  sub->add_option("--duration", opts->duration_s, "Seconds per run")->capture_default_str()->check(CLI::PositiveNumber);
  sub->add_option("--json", opts->json, "Also write the figures as JSON");
  sub->callback([opts] { run_bench(*opts); });
}

}  // namespace rtslam::cli
