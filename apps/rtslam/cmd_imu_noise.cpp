// rtslam imu-noise --dataset euroc:DIR: the IMU noise densities a filter should assume on a recording, measured by
// integrating the recorded IMU between its ground-truth states (eval/imu_noise.hpp). Evaluation only: it reads the
// ground truth, which the estimator never does.
#include <fstream>
#include <iostream>
#include <memory>

#include <fmt/format.h>

#include "commands.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/eval/imu_noise.hpp"

namespace rtslam::cli {

namespace {
struct ImuNoiseArgs {
  std::string dataset, json_out;
  eval::ImuNoiseOptions options;
};

void run_imu_noise(const ImuNoiseArgs& a) {
  a.options.validate();
  const eval::ImuNoiseInput in = eval::read_imu_noise_input(a.dataset);
  const eval::ImuNoiseReport r = eval::measure_imu_noise(in.imu, in.states, a.options);
  std::cout << eval::format_imu_noise(r, in.calibration);
  if (!a.json_out.empty()) {
    nlohmann::json j = eval::to_json(r);
    j["dataset"] = a.dataset;
    std::ofstream f(a.json_out);
    if (!f) throw IoError(fmt::format("{}: cannot write", a.json_out));
    f << j.dump(1) << '\n';
    if (!f) throw IoError(fmt::format("{}: write failed", a.json_out));
    std::cout << "wrote " << a.json_out << '\n';
  }
}
}  // namespace

void register_imu_noise(CLI::App& app) {
  auto a = std::make_shared<ImuNoiseArgs>();
  auto* sub = app.add_subcommand(
      "imu-noise",
      "Measure the IMU noise densities of a recording against its ground-truth states (values for the imu: section)");
  sub->add_option("--dataset", a->dataset,
                  "EuRoC folder with imu0/data.csv and state_groundtruth_estimate0/data.csv (euroc:DIR or DIR)")
      ->required();
  sub->add_option("--windows", a->options.windows_s, "integration windows (s), comma-separated")
      ->delimiter(',')
      ->capture_default_str();
  sub->add_option("--from", a->options.from_s, "use windows from this many seconds after the first state")
      ->capture_default_str();
  sub->add_option("--to", a->options.to_s, "... up to this many seconds after it (0: the end)")->capture_default_str();
  sub->add_option("--rest-speed", a->options.rest_speed,
                  "ground-truth speed (m/s) below which a window is at rest (split at rest / in flight)")
      ->capture_default_str();
  sub->add_option("--json", a->json_out, "also write the figures as JSON to this file");
  sub->callback([a] { run_imu_noise(*a); });
}

}  // namespace rtslam::cli
