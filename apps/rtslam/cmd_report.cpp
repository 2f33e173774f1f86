// rtslam report: placeholder until its issue lands; it says so and exits with code 2.
#include <iostream>

#include "commands.hpp"

namespace rtslam::cli {

void register_report(CLI::App& app) {
  auto* sub = app.add_subcommand("report", "Write an HTML report with the paper's figures for a run or a batch (not implemented yet)");
  sub->callback([] {
    std::cerr << "rtslam report: not implemented yet\n";
    throw CommandExit{2};
  });
}

}  // namespace rtslam::cli
