#pragma once
// Template parts of yaml.hpp.
#include <fmt/format.h>

#include "rtslam/core/error.hpp"

namespace rtslam {

template <class T>
void YamlMap::get(const std::string& key, T& value) {
  if (!node_ || !node_[key]) return;
  used_.insert(key);
  try {
    value = node_[key].as<T>();
  } catch (const YAML::Exception& e) {
    throw ConfigError(fmt::format("{}: cannot read '{}' ({})", where_, path_of(key), e.msg));
  }
}

template <class T>
T YamlMap::require(const std::string& key) {
  if (!has(key)) throw ConfigError(fmt::format("{}: missing required key '{}'", where_, path_of(key)));
  T value{};
  get(key, value);
  return value;
}

}  // namespace rtslam
