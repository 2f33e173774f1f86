// rtslam bench: placeholder until its issue lands; it says so and exits with code 2.
#include <iostream>

#include "commands.hpp"

namespace rtslam::cli {

void register_bench(CLI::App& app) {
  auto* sub = app.add_subcommand("bench", "Run the end-to-end per-frame benchmark (not implemented yet)");
  sub->callback([] {
    std::cerr << "rtslam bench: not implemented yet\n";
    throw CommandExit{2};
  });
}

}  // namespace rtslam::cli
