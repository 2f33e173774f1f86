#include "rtslam/core/log.hpp"

#include <mutex>

#include <spdlog/sinks/stdout_color_sinks.h>

#include "rtslam/core/error.hpp"

namespace rtslam {
namespace {
std::mutex g_mutex;
spdlog::level::level_enum g_level = spdlog::level::info;
}  // namespace

std::shared_ptr<spdlog::logger> logger(const std::string& module) {
  std::lock_guard lock(g_mutex);
  auto existing = spdlog::get(module);
  if (existing) return existing;
  auto created = spdlog::stderr_color_mt(module);
  created->set_level(g_level);
  created->set_pattern("[%n] %^%l%$: %v");
  return created;
}

void set_log_level(const std::string& level) {
  const auto parsed = spdlog::level::from_str(level);
  if (parsed == spdlog::level::off && level != "off") {
    throw ConfigError(fmt::format("log level '{}' is not one of trace, debug, info, warn, error, off", level));
  }
  std::lock_guard lock(g_mutex);
  g_level = parsed;
  spdlog::apply_all([parsed](const std::shared_ptr<spdlog::logger>& l) { l->set_level(parsed); });
}

}  // namespace rtslam
