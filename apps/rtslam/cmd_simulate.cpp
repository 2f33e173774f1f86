// rtslam simulate: writes a simulated sequence (rendered camera images, IMU, exact ground truth) as an EuRoC/ASL
// folder plus groundtruth.txt (TUM), so that rtslam and other systems can run on the same data.
//   rtslam simulate --preset high-dynamic --seed 3 --out /tmp/hd
//   rtslam simulate --preset handheld --trajectory follow:../shared/datasets/euroc-groundtruth/V2_01_easy.txt --out d
#include <chrono>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "commands.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/sim/simulation.hpp"

namespace rtslam::cli {

namespace {

struct SimulateArgs {
  std::string preset = "handheld";
  std::string world;
  std::string trajectory;
  std::optional<std::uint64_t> seed;
  std::optional<double> duration_s;
  std::string out;
  std::optional<int> threads;
  std::optional<double> start_offset_s;
  bool no_imu = false;
  bool motion_blur = false;
  bool stereo = false;
  bool hide_groundtruth = false;
};

void run_simulate(const SimulateArgs& a) {
  sim::SimConfig c = sim::SimConfig::load(a.preset);
  if (!a.world.empty()) {
    const auto names = sim::WorldConfig::preset_names();
    c.world = std::find(names.begin(), names.end(), a.world) != names.end() ? sim::WorldConfig::preset(a.world)
                                                                             : sim::WorldConfig::from_file(a.world);
  }
  if (!a.trajectory.empty()) c.trajectory = a.trajectory;
  if (a.seed) c.seed = *a.seed;
  if (a.duration_s) c.duration_s = *a.duration_s;
  if (a.start_offset_s) c.start_offset_s = *a.start_offset_s;
  if (a.stereo) c.stereo = true;
  if (a.threads) c.render.threads = *a.threads;
  if (a.no_imu) c.imu_enabled = false;
  if (a.motion_blur) c.render.motion_blur = true;
  c.validate();
  const auto start = std::chrono::steady_clock::now();
  const auto simulation = sim::Simulation::create(c);
  simulation->write_euroc(a.out, a.hide_groundtruth);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::cout << fmt::format("rtslam simulate: wrote {} images, {} IMU samples and {} ground-truth poses to {} in "
                           "{:.1f} s (preset {}, {}, seed {})\n",
                           simulation->image_times().size(), simulation->imu_samples().size(),
                           simulation->ground_truth().poses.size(), a.out, s, c.name,
                           simulation->trajectory().describe(), c.seed);
}

}  // namespace

void register_simulate(CLI::App& app) {
  auto args = std::make_shared<SimulateArgs>();
  auto* sub = app.add_subcommand(
      "simulate", "Simulate a camera/IMU sequence with exact ground truth and write it as an EuRoC folder");
  sub->add_option("--preset", args->preset,
                  "built-in preset (handheld, high-dynamic, hall, ground) or a preset YAML file (see config/sim/)")
      ->capture_default_str();
  sub->add_option("--world", args->world, "world preset (room, small-room, hall) or world YAML file");
  sub->add_option("--trajectory", args->trajectory,
                  "handheld, high-dynamic, ground, follow:FILE (TUM text or EuRoC CSV, smoothed, synthetic IMU) or "
                  "recorded:DIR (an EuRoC folder's recorded states and recorded IMU, images rendered at the recorded "
                  "times)");
  sub->add_option("--start-offset", args->start_offset_s,
                  "follow/recorded trajectories: start this many seconds into the recording");
  sub->add_flag("--stereo", args->stereo, "render camera 1 too (EuRoC cam1, or the recorded folder's cam1)");
  sub->add_flag("--hide-groundtruth", args->hide_groundtruth,
                "write the ground truth to OUT/groundtruth/ only, not into mav0/ (runs then see sensors only)");
  sub->add_option("--seed", args->seed, "redraws every noise source (pixel noise, IMU noise, initial biases)");
  sub->add_option("--duration", args->duration_s, "seconds to simulate");
  sub->add_option("--out", args->out, "output folder (EuRoC ASL layout + groundtruth.txt)")->required();
  sub->add_option("--threads", args->threads, "rendering threads");
  sub->add_flag("--no-imu", args->no_imu, "camera only");
  sub->add_flag("--motion-blur", args->motion_blur, "render motion blur over the exposure time");
  sub->callback([args] { run_simulate(*args); });
}

}  // namespace rtslam::cli
