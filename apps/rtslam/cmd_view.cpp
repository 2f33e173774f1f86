// rtslam view OUT: replays a finished run's output folder in the web viewer (src/rtslam/viz/viewer.hpp,
// docs/viewer.md) with a time slider: trajectory.csv, frames.csv, groundtruth.txt, map.ply, summary.json and the
// per-frame overlays of `rtslam run --overlays DIR` (OUT/overlays by default). Serves until Ctrl-C.
#include <atomic>
#include <chrono>
#include <csignal>
#include <iostream>
#include <memory>
#include <thread>

#include <fmt/format.h>

#include "commands.hpp"
#include "rtslam/viz/replay.hpp"
#include "rtslam/viz/viewer.hpp"

namespace rtslam::cli {

namespace {

struct ViewArgs {
  std::string dir;
  std::string address = "127.0.0.1:0";
  std::string overlays;
  std::string align = "sim3";
  double exit_after_s = 0.0;
};

std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int) { g_stop = true; }

}  // namespace

void register_view(CLI::App& app) {
  auto a = std::make_shared<ViewArgs>();
  auto* sub = app.add_subcommand("view", "Replay a finished run's output folder in the web viewer (time slider)");
  sub->add_option("OUT", a->dir, "output folder of rtslam run (--out)")->required();
  sub->add_option("--addr", a->address,
                  "ADDR:PORT to serve on (port 0: a free one); loopback unless an address is given, 0.0.0.0 for "
                  "every interface")
      ->capture_default_str();
  sub->add_option("--overlays", a->overlays, "overlay folder of rtslam run --overlays (default: OUT/overlays)");
  sub->add_option("--align", a->align, "ground truth drawn aligned by: sim3, se3, posyaw or origin")
      ->capture_default_str();
  sub->add_option("--exit-after", a->exit_after_s, "stop serving after this many seconds (0: at Ctrl-C)")
      ->check(CLI::NonNegativeNumber);
  sub->callback([a] {
    viz::ViewerOptions o;
    o.address = a->address;
    o.ground_truth_alignment = a->align;
    o.validate();
    viz::RunRecording rec = viz::load_run(a->dir, a->overlays);
    const std::size_t poses = rec.history.size(), landmarks = rec.map.size(), overlays = rec.overlays.size();
    viz::Viewer viewer(o);
    viewer.show_recording(std::move(rec));
    std::signal(SIGINT, on_stop_signal);
    std::signal(SIGTERM, on_stop_signal);
    std::cout << fmt::format("rtslam view: {} ({} poses, {} landmarks, {} overlays)\nviewer: {}\n", a->dir, poses,
                             landmarks, overlays, viewer.url())
              << std::flush;
    const auto start = std::chrono::steady_clock::now();
    while (!g_stop) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      if (a->exit_after_s > 0.0 &&
          std::chrono::steady_clock::now() - start > std::chrono::duration<double>(a->exit_after_s)) {
        break;
      }
    }
    viewer.stop();
    std::cout << "rtslam view: stopped\n";
  });
}

}  // namespace rtslam::cli
