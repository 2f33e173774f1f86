#pragma once
// Template parts of yaml.hpp.
#include <limits>

#include <fmt/format.h>

#include <cstdint>
#include <string>
#include <type_traits>

#include "rtslam/core/error.hpp"

namespace rtslam {

namespace detail {
/// What a key of type T must hold, for messages ("an integer in [-2147483648, 2147483647]").
template <class T>
std::string yaml_type_name() {
  if constexpr (std::is_same_v<T, bool>) {
    return "true or false";
  } else if constexpr (std::is_integral_v<T>) {
    return fmt::format("an integer in [{}, {}]", std::numeric_limits<T>::min(), std::numeric_limits<T>::max());
  } else if constexpr (std::is_floating_point_v<T>) {
    return "a number";
  } else if constexpr (std::is_same_v<T, std::string>) {
    return "a string";
  } else {
    return "a value of the expected kind";
  }
}
/// The node as written in the file (a scalar's text; "a list" / "a mapping" otherwise).
std::string yaml_node_text(const YAML::Node& n);
}  // namespace detail

template <class T>
void YamlMap::get(const std::string& key, T& value) {
  if (!node_ || !node_[key]) return;
  used_.insert(key);
  try {
    value = node_[key].as<T>();
  } catch (const YAML::Exception&) {
    // yaml-cpp says only "bad conversion": name the key, the value and what it must be.
    throw ConfigError(fmt::format("{}: {} = {} must be {}", where_, path_of(key), detail::yaml_node_text(node_[key]),
                                  detail::yaml_type_name<T>()));
  }
}

template <class T>
T YamlMap::require(const std::string& key) {
  if (!has(key)) throw ConfigError(fmt::format("{}: missing required key '{}'", where_, path_of(key)));
  T value{};
  get(key, value);
  return value;
}

template <class F>
void validate_in_file(const std::string& file, F&& check) {
  try {
    check();
  } catch (const ConfigError& e) {
    throw ConfigError(fmt::format("{}: {}", file, e.what()));
  }
}

}  // namespace rtslam
