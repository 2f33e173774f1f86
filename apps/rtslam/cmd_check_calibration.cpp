// rtslam check-calibration: the camera–IMU rotation and time offset measured from a dataset's first seconds of motion
// against its calibration (src/rtslam/calib/check.hpp, docs/configuration.md "Calibration check"); also the pre-pass
// of `rtslam run` (calibration_prepass.hpp). Exit status: 0 ok or not enough motion, 2 a warning, 1 failed.
#include <chrono>
#include <fstream>
#include <iostream>

#include <fmt/format.h>

#include "calibration_prepass.hpp"
#include "commands.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"

namespace rtslam::cli {

namespace {

struct CheckCalibrationOptions {
  std::string dataset;
  std::string config;
  std::string calibration;
  std::optional<double> duration_s;
  double start_at_s = 0.0;
  std::string json;
};

// The configured t_d of a run: imu/time_offset, else the rig's.
std::optional<TimeNs> calcheck_configured_offset(const pipeline::ImageSlamOptions& o) {
  if (o.imu.time_offset_s) return from_seconds(*o.imu.time_offset_s);
  return std::nullopt;
}

void calcheck_command(const CheckCalibrationOptions& co) {
  pipeline::ImageSlamOptions o =
      co.config.empty() ? pipeline::ImageSlamOptions{} : pipeline::load_image_slam_config(co.config);
  calib::CheckOptions c = o.imu.calibration_check;
  if (co.duration_s) c.duration_s = *co.duration_s;
  c.validate();
  io::DatasetOptions dopt;
  dopt.calibration = co.calibration;
  dopt.start_offset_s = co.start_at_s;
  dopt.rate_hz = o.rate_hz;
  const calib::CheckResult r =
      calib::check_dataset_calibration(co.dataset, dopt, o.camera, calcheck_configured_offset(o), c);
  for (const auto& l : r.lines()) std::cout << l << '\n';
  std::cout << fmt::format("  ({:.0f} ms)\n", r.cost_ms) << std::flush;
  if (!co.json.empty()) {
    std::ofstream f(co.json);
    f << r.to_json().dump(2) << '\n';
    if (!f) throw IoError(fmt::format("{}: cannot write the result", co.json));
  }
  if (r.verdict == calib::Verdict::failed) throw DataError("calibration check failed: " + r.reason);
  if (r.verdict == calib::Verdict::warning) throw CommandExit{2};
}

}  // namespace

std::optional<calib::CheckResult> calibration_prepass(const std::string& dataset_spec,
                                                      const io::DatasetOptions& dataset_options,
                                                      const pipeline::ImageSlamOptions& o, bool simulated,
                                                      std::string& skipped, int prefetch_threads) {
  if (o.robot != "inertial") {
    skipped = o.robot + " robot: the IMU is not used";
    return std::nullopt;
  }
  if (!o.imu.calibration_check.enabled) {
    skipped = "imu/calibration_check/enabled is false";
    return std::nullopt;
  }
  if (simulated) {
    skipped = "simulated input: its calibration is exact";
    return std::nullopt;
  }
  if (dataset_spec.rfind("camera:", 0) == 0) {
    skipped = "live input: it cannot be read twice (check a recording of the rig with rtslam check-calibration)";
    return std::nullopt;
  }
  calib::CheckResult r;
  try {
    r = calib::check_dataset_calibration(dataset_spec, dataset_options, o.camera, calcheck_configured_offset(o),
                                         o.imu.calibration_check, prefetch_threads);
  } catch (const Error& e) {
    // The run opened this dataset already: a problem here is the check's (e.g. bad data under the error policy
    // inside the window), reported, not fatal.
    r.verdict = calib::Verdict::failed;
    r.reason = e.what();
  }
  const auto log = logger("calib");
  for (const auto& w : r.warnings) log->warn("calibration check: {}", w);
  if (r.verdict == calib::Verdict::failed || r.verdict == calib::Verdict::not_enough_motion) {
    log->info("calibration check: {} ({})", calib::to_string(r.verdict), r.reason);
  }
  return r;
}

std::string calibration_summary(const std::optional<calib::CheckResult>& check, const std::string& skipped,
                                const calib::StreamReport& run_stream, nlohmann::json& summary) {
  nlohmann::json j = check ? check->to_json() : nlohmann::json{{"verdict", "skipped"}, {"reason", skipped}};
  if (check) j["window_stream"] = j["stream"];
  j["stream"] = run_stream.to_json();
  summary["calibration_check"] = j;
  std::string out;
  if (!check) {
    out = fmt::format("  calibration check: skipped ({})\n", skipped);
  } else {
    const calib::CheckResult& r = *check;
    out = fmt::format("  calibration check: {} in {:.0f} ms; camera–IMU rotation {}, time offset {}{}\n",
                      calib::to_string(r.verdict), r.cost_ms,
                      r.rotation_measured ? fmt::format("{:.2f} deg from T_RS{}", r.rotation_error_deg,
                                                        r.looks_inverted ? " (looks like its inverse)" : "")
                                          : std::string("not measured"),
                      r.offset_measured ? fmt::format("{:.1f} ms (configured {:.1f} ms)", r.t_d_measured_ms,
                                                      r.t_d_configured_ms)
                                        : std::string("not measured"),
                      r.reason.empty() ? std::string() : " — " + r.reason);
    for (const auto& w : r.warnings) out += "    WARNING: " + w + "\n";
  }
  out += "  input timing: " + run_stream.line() + "\n";
  return out;
}

void register_check_calibration(CLI::App& app) {
  auto opts = std::make_shared<CheckCalibrationOptions>();
  auto* sub = app.add_subcommand(
      "check-calibration",
      "Measure the camera–IMU rotation and time offset from a dataset's first seconds of motion and compare them with "
      "its calibration (exit 2 on a disagreement)");
  sub->add_option("--dataset", opts->dataset, "KIND:PATH of a dataset with a camera and an IMU")->required();
  sub->add_option("--config", opts->config,
                  "Run configuration: slam/camera, imu/time_offset and the imu/calibration_check keys");
  sub->add_option("--calibration", opts->calibration, "Calibration file to check instead of the dataset's own")
      ->check(CLI::ExistingFile);
  sub->add_option("--duration", opts->duration_s, "Seconds of motion analysed (default: the config's, 6)")
      ->check(CLI::PositiveNumber);
  sub->add_option("--start-at", opts->start_at_s, "Start this many seconds after the first measurement")
      ->check(CLI::NonNegativeNumber);
  sub->add_option("--json", opts->json, "Write the result as JSON to this file");
  sub->callback([opts] { calcheck_command(*opts); });
}

}  // namespace rtslam::cli
