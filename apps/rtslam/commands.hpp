#pragma once
// Each subcommand lives in its own cmd_<name>.cpp and registers itself on the root app.
// A subcommand reports failure by throwing an rtslam::Error (one line, exit 1) or CommandExit (its own code).
#include <CLI/CLI.hpp>

namespace rtslam::cli {

/// Thrown by a subcommand that must end with a specific exit code after printing its own message.
struct CommandExit {
  int code;
};

void register_run(CLI::App& app);
void register_simulate(CLI::App& app);
void register_eval(CLI::App& app);
void register_batch(CLI::App& app);
void register_report(CLI::App& app);
void register_bench(CLI::App& app);
void register_imu_noise(CLI::App& app);
void register_view(CLI::App& app);
void register_check_calibration(CLI::App& app);
void register_soak(CLI::App& app);

}  // namespace rtslam::cli
