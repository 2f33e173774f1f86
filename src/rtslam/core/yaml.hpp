#pragma once
// Strict YAML reading for options structs: every key read is recorded, and finish() rejects keys nobody read,
// naming the file and the key. Errors say the file, the key path, the value and the violated bound.
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <yaml-cpp/yaml.h>

namespace rtslam {

/// Loads a YAML file; throws IoError (missing, a directory, unreadable) or ConfigError (syntax, a key given twice in
/// one mapping, nothing in the file but comments) naming the file.
YAML::Node load_yaml_file(const std::string& path);

/// Throws ConfigError naming `path`, the line and the key path when a mapping in `node` has a key twice (yaml-cpp
/// keeps both and a lookup sees only the first, so the second would be ignored silently).
void check_unique_keys(const YAML::Node& node, const std::string& path);

/// A view of one YAML mapping with key tracking. `where` names the file and key path for messages.
class YamlMap {
 public:
  /// A file's top-level mapping: `where` is the file (child() appends the key path to it).
  YamlMap(YAML::Node node, std::string where);

  bool has(const std::string& key) const;
  /// Reads key into value if present (value keeps its default otherwise). Throws ConfigError on a bad type.
  template <class T>
  void get(const std::string& key, T& value);
  /// Reads a key that must be present.
  template <class T>
  T require(const std::string& key);
  /// A nested mapping (must be a map if present; an empty map if absent).
  YamlMap child(const std::string& key);
  /// Reads a fixed-size list of doubles, or a row-major matrix given as a flat list or a list of rows.
  void get_matrix(const std::string& key, Eigen::Ref<Eigen::MatrixXd> value);
  /// Throws ConfigError naming the first key that was present but never read.
  void finish() const;

  const std::string& where() const { return where_; }
  /// The file the mapping came from (the `where` of the top-level map), for messages of checks made later.
  const std::string& file() const { return file_; }
  const YAML::Node& node() const { return node_; }
  std::string path_of(const std::string& key) const;

 private:
  YAML::Node node_;
  std::string where_;
  std::string file_;
  std::set<std::string> used_;
};

/// Throws ConfigError "<where>: <key> = <value> must be <bound>" if !ok.
void require_bound(bool ok, const std::string& where, const std::string& key, double value, const std::string& bound);

/// Runs `check` (an options struct's validate()); a ConfigError it throws is rethrown with "<file>: " in front, so
/// that a bound violated by a value read from `file` names the file as well as the key path.
template <class F>
void validate_in_file(const std::string& file, F&& check);

}  // namespace rtslam

#include "rtslam/core/yaml_impl.hpp"
