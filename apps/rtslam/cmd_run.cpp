// rtslam run: placeholder, replaced by the walking skeleton.
#include <iostream>

#include "commands.hpp"

namespace rtslam::cli {

void register_run(CLI::App& app) {
  auto* sub = app.add_subcommand("run", "Run SLAM on a dataset, or on the built-in simulated demo");
  sub->callback([] { std::cerr << "rtslam run: not implemented yet\n"; throw CommandExit{2}; });
}

}  // namespace rtslam::cli
