#pragma once
// One named spdlog logger per module ("filter", "io", ...), all writing to stderr.
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

namespace rtslam {

/// The logger of a module, created on first use. Nothing above debug level inside per-frame loops.
std::shared_ptr<spdlog::logger> logger(const std::string& module);

/// Sets the level of every rtslam logger (existing and future): "trace", "debug", "info", "warn", "error", "off".
void set_log_level(const std::string& level);

}  // namespace rtslam
