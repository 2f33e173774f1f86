#pragma once
// The calibration check of `rtslam run` (src/rtslam/calib/check.hpp), kept out of cmd_run.cpp: a pre-pass over the
// dataset re-opened (the run's own stream is not touched), and the run's `calibration_check` summary entry.
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "rtslam/calib/check.hpp"
#include "rtslam/calib/stream.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/pipeline/image_slam.hpp"

namespace rtslam::cli {

/// Inertial runs on a dataset with imu/calibration_check/enabled: checks the calibration on the dataset opened again
/// with `dataset_options` (from its start offset), logs its warnings, and returns it; nullopt otherwise (`skipped`
/// then says why). A dataset that cannot be checked is a result with verdict failed, never an exception. Images are
/// decoded ahead in `prefetch_threads` threads (the run's --prefetch; < 0: the default).
std::optional<calib::CheckResult> calibration_prepass(const std::string& dataset_spec,
                                                      const io::DatasetOptions& dataset_options,
                                                      const pipeline::ImageSlamOptions& options, bool simulated,
                                                      std::string& skipped, int prefetch_threads = -1);

/// summary["calibration_check"]: the check (or {"verdict": "skipped", "reason"}) with the whole run's stream report
/// under "stream"; returns the lines for the printed summary.
std::string calibration_summary(const std::optional<calib::CheckResult>& check, const std::string& skipped,
                                const calib::StreamReport& run_stream, nlohmann::json& summary);

}  // namespace rtslam::cli
