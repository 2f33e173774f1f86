#pragma once
// A test's own folder under the system's temporary folder: <tmp>/rtslam_<prefix>_<name>_<pid>, emptied first (a
// previous run's leftovers) and created unless asked not to (for code that must create it itself). The pid keeps
// two processes apart (ctest -j runs a bundle's entries side by side).
#include <unistd.h>

#include <filesystem>
#include <string>
#include <string_view>

namespace rtslam::support {

inline std::filesystem::path fresh_temp_dir(std::string_view prefix, std::string_view name, bool create = true) {
  const std::filesystem::path d = std::filesystem::temp_directory_path() /
                                  ("rtslam_" + std::string(prefix) + "_" + std::string(name) + "_" +
                                   std::to_string(::getpid()));
  std::filesystem::remove_all(d);
  if (create) std::filesystem::create_directories(d);
  return d;
}

}  // namespace rtslam::support
