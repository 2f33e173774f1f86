// rtslam batch: placeholder until its issue lands; it says so and exits with code 2.
#include <iostream>

#include "commands.hpp"

namespace rtslam::cli {

void register_batch(CLI::App& app) {
  auto* sub = app.add_subcommand("batch", "Run a matrix of datasets x configs x seeds and aggregate the results (not implemented yet)");
  sub->callback([] {
    std::cerr << "rtslam batch: not implemented yet\n";
    throw CommandExit{2};
  });
}

}  // namespace rtslam::cli
