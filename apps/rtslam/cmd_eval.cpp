// rtslam eval: placeholder until its issue lands; it says so and exits with code 2.
#include <iostream>

#include "commands.hpp"

namespace rtslam::cli {

void register_eval(CLI::App& app) {
  auto* sub = app.add_subcommand("eval", "Evaluate an estimated trajectory against ground truth (ATE, RPE, NEES) (not implemented yet)");
  sub->callback([] {
    std::cerr << "rtslam eval: not implemented yet\n";
    throw CommandExit{2};
  });
}

}  // namespace rtslam::cli
