// rtslam simulate: placeholder until its issue lands; it says so and exits with code 2.
#include <iostream>

#include "commands.hpp"

namespace rtslam::cli {

void register_simulate(CLI::App& app) {
  auto* sub = app.add_subcommand("simulate", "Simulate a camera/IMU sequence with exact ground truth (not implemented yet)");
  sub->callback([] {
    std::cerr << "rtslam simulate: not implemented yet\n";
    throw CommandExit{2};
  });
}

}  // namespace rtslam::cli
