#pragma once
// --prefetch N / --no-prefetch, shared by `rtslam run` and `rtslam bench --pipeline`: images decoded ahead of the
// filter in N worker threads (io/prefetch.hpp). Default: io::default_prefetch_threads() (one per hardware thread
// but the filter's, at most 4; off on one core). The stream is the same either way.
#include <CLI/CLI.hpp>

#include "rtslam/io/prefetch.hpp"

namespace rtslam::cli {

/// Registers both options on `sub`; `threads` (< 0: the default) is read when the command runs.
inline void add_prefetch_options(CLI::App& sub, int& threads) {
  sub.add_option("--prefetch", threads,
                 "Decode images ahead of the filter in this many threads (default: one per core but the filter's, "
                 "at most 4; 0: off)")
      ->check(CLI::Range(0, 64));
  sub.add_flag_callback(
      "--no-prefetch", [&threads] { threads = 0; }, "Decode each image when the filter needs it");
}

}  // namespace rtslam::cli
