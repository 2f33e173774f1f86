// viz_live_run: a short simulated image-SLAM run (pipeline::run_image_slam on pipeline::make_sim_dataset with
// config/sim_mono.yaml) that feeds rtslam::viz through the run's observer as `rtslam run --view --overlays --video`
// does (apps/rtslam/cmd_run.cpp), with options the browser tests need (--wait-client, --hold on stdin) and the
// measurement of the viewer's cost on the filter (make_report and push timed apart; docs/viewer.md).
//
//   viz_live_run [--duration S] [--seed N] [--view ADDR:PORT] [--wait-client S] [--overlays DIR] [--video FILE]
//                [--hold]
// Prints "viewer: URL" (with --view), then one line "result: key=value ..." at the end: frames, final landmarks,
// the median per-frame SLAM time, the median cost of make_report and push, dropped frames. With --hold it keeps
// serving until stdin closes (or SIGTERM).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <unistd.h>

#include "rtslam/io/dataset.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/viz/overlay.hpp"
#include "rtslam/viz/report.hpp"
#include "rtslam/viz/viewer.hpp"

namespace {

using namespace rtslam;
using Clock = std::chrono::steady_clock;

// Keeps a (shared, not copied) reference to the last image the source gave, so that the observer can see it: the
// pipeline's observer does not receive the image yet.
class ImageTap final : public io::Source {
 public:
  explicit ImageTap(std::unique_ptr<io::Source> inner) : inner_(std::move(inner)) {}
  std::optional<io::Measurement> next() override {
    auto m = inner_->next();
    if (m) {
      if (const auto* f = std::get_if<io::ImageFrame>(&*m)) {
        last_ = f->image;
        taken_ = Clock::now();
      }
    }
    return m;
  }
  const io::SourceStats& stats() const override { return inner_->stats(); }
  std::optional<std::size_t> image_count() const override { return inner_->image_count(); }
  const cv::Mat& last() const { return last_; }
  Clock::time_point taken() const { return taken_; }

 private:
  std::unique_ptr<io::Source> inner_;
  cv::Mat last_;
  Clock::time_point taken_{};
};

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

std::atomic<bool> g_stop{false};
extern "C" void on_signal(int) { g_stop = true; }

}  // namespace

int main(int argc, char** argv) {
  double duration = 4.0, wait_client_s = 0.0;
  std::uint64_t seed = 1;
  std::string view, overlays, video, config = std::string(RTSLAM_SOURCE_DIR) + "/config/sim_mono.yaml";
  bool hold = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "viz_live_run: " << a << " needs a value\n";
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--duration") duration = std::stod(value());
    else if (a == "--seed") seed = std::stoull(value());
    else if (a == "--view") view = value();
    else if (a == "--wait-client") wait_client_s = std::stod(value());
    else if (a == "--overlays") overlays = value();
    else if (a == "--video") video = value();
    else if (a == "--config") config = value();
    else if (a == "--hold") hold = true;
    else {
      std::cerr << "viz_live_run: unknown argument " << a << '\n';
      return 2;
    }
  }
  try {
    pipeline::ImageSlamOptions o = pipeline::load_image_slam_config(config);
    o.seed = seed;
    o.sim_duration_s = duration;
    io::Dataset ds = pipeline::make_sim_dataset(o);
    auto tap_owner = std::make_unique<ImageTap>(std::move(ds.source));
    ImageTap& tap = *tap_owner;
    ds.source = std::move(tap_owner);

    std::optional<viz::Viewer> viewer;
    if (!view.empty()) {
      viz::ViewerOptions vo;
      vo.address = view;
      viewer.emplace(vo);
      viewer->set_title(fmt::format("{} (simulated), seed {}", ds.name, seed));
      if (ds.ground_truth) viewer->set_ground_truth(*ds.ground_truth);
      std::cout << "viewer: " << viewer->url() << std::endl;
      const auto until = Clock::now() + std::chrono::duration<double>(wait_client_s);
      while (wait_client_s > 0 && viewer->stats().clients == 0 && Clock::now() < until) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
    }
    std::optional<viz::OverlayWriter> overlay_writer;
    if (!overlays.empty()) overlay_writer.emplace(overlays);
    std::optional<viz::VideoWriter> video_writer;
    if (!video.empty()) video_writer.emplace(video);

    std::vector<double> report_us, push_us;
    const auto observer = [&](const pipeline::ImageSlamFrame& f) {
      const double slam_ms = std::chrono::duration<double, std::milli>(Clock::now() - tap.taken()).count();
      const auto t0 = Clock::now();
      viz::FrameReport r = viz::make_report(f, tap.last());
      r.stats.time_total_ms = slam_ms;  // image out of the source → observer (the pipeline will pass its stats)
      r.has_timing = true;
      const auto t1 = Clock::now();
      if (overlay_writer) overlay_writer->write(r);
      if (video_writer) video_writer->write(r);
      if (viewer) {
        const auto t2 = Clock::now();
        viewer->push(std::move(r));
        push_us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - t2).count());
      }
      report_us.push_back(std::chrono::duration<double, std::micro>(t1 - t0).count());
    };
    const pipeline::ImageSlamResult result = pipeline::run_image_slam(ds, o, {}, observer);
    if (overlay_writer) overlay_writer->close();
    if (video_writer) video_writer->close();
    std::vector<double> slam_ms;
    for (const auto& s : result.frames) slam_ms.push_back(s.time_total_ms);
    const viz::ViewerStats vs = viewer ? viewer->stats() : viz::ViewerStats{};
    if (viewer) viewer->finish();
    std::cout << fmt::format(
                     "result: frames={} landmarks={} euclidean={} slam_median_ms={:.4f} make_report_median_us={:.2f} "
                     "push_median_us={:.2f} push_max_us={:.2f} pushed={} dropped={} clients={}",
                     result.frames.size(), result.landmarks_final, result.euclidean_final, median(slam_ms),
                     median(report_us), median(push_us),
                     push_us.empty() ? 0.0 : *std::max_element(push_us.begin(), push_us.end()), vs.pushed,
                     vs.dropped, vs.clients)
              << std::endl;
    if (hold) {
      std::signal(SIGTERM, on_signal);
      std::signal(SIGINT, on_signal);
      // Until stdin closes (the test's pipe) or a signal.
      std::thread reader([] {
        char buf[256];
        while (::read(STDIN_FILENO, buf, sizeof buf) > 0) {
        }
        g_stop = true;
      });
      reader.detach();
      while (!g_stop) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    if (viewer) viewer->stop();
  } catch (const std::exception& e) {
    std::cerr << "viz_live_run: error: " << e.what() << '\n';
    return 1;
  }
  return 0;
}
