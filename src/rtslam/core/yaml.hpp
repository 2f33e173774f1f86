#pragma once
// Strict YAML reading for options structs: every key read is recorded, and finish() rejects keys nobody read,
// naming the file and the key. Errors say the file, the key path, the value and the violated bound.
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <yaml-cpp/yaml.h>

namespace rtslam {

/// Loads a YAML file; throws IoError (missing/unreadable) or ConfigError (syntax) naming the file.
YAML::Node load_yaml_file(const std::string& path);

/// A view of one YAML mapping with key tracking. `where` names the file and key path for messages.
class YamlMap {
 public:
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
  const YAML::Node& node() const { return node_; }
  std::string path_of(const std::string& key) const;

 private:
  YAML::Node node_;
  std::string where_;
  std::set<std::string> used_;
};

/// Throws ConfigError "<where>: <key> = <value> must be <bound>" if !ok.
void require_bound(bool ok, const std::string& where, const std::string& key, double value, const std::string& bound);

}  // namespace rtslam

#include "rtslam/core/yaml_impl.hpp"
