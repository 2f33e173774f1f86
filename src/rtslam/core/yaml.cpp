#include "rtslam/core/yaml.hpp"

#include <cmath>
#include <filesystem>
#include <set>

namespace rtslam {

YAML::Node load_yaml_file(const std::string& path) {
  if (!std::filesystem::exists(path)) throw IoError(fmt::format("{}: file not found", path));
  if (std::filesystem::is_directory(path)) throw IoError(fmt::format("{}: is a directory, not a YAML file", path));
  if (!std::filesystem::is_regular_file(path)) {
    throw IoError(fmt::format("{}: not a regular file (a pipe or device), not a YAML file", path));
  }
  YAML::Node node;
  try {
    node = YAML::LoadFile(path);
  } catch (const YAML::ParserException& e) {
    throw ConfigError(fmt::format("{}: malformed YAML at line {}: {}", path, e.mark.line + 1, e.msg));
  } catch (const YAML::Exception& e) {
    throw IoError(fmt::format("{}: cannot read YAML: {}", path, e.msg));
  }
  if (!node || node.IsNull()) {
    throw ConfigError(fmt::format("{}: no settings in the file (empty, or only comments)", path));
  }
  check_unique_keys(node, path);
  return node;
}

namespace {
// Each mapping and list once: an alias is the anchored node itself in yaml-cpp, so following every path would visit
// a node as often as it is referenced (exponentially often through nested aliases) or forever (an alias inside its
// own anchor). Loaded nodes are told apart by where they start in the file.
using Visited = std::set<std::pair<int, int>>;

void check_unique_keys_at(const YAML::Node& node, const std::string& path, const std::string& key_path,
                          Visited& visited) {
  if (!node.IsSequence() && !node.IsMap()) return;
  const YAML::Mark mark = node.Mark();
  if (!mark.is_null() && !visited.insert({mark.pos, mark.line}).second) return;
  if (node.IsSequence()) {
    for (std::size_t i = 0; i < node.size(); ++i) {
      check_unique_keys_at(node[i], path, fmt::format("{}[{}]", key_path, i), visited);
    }
    return;
  }
  std::set<std::string> seen;
  for (const auto& kv : node) {
    const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : std::string("?");
    const std::string here = key_path.empty() ? key : key_path + "/" + key;
    if (kv.first.IsScalar() && !seen.insert(key).second) {
      throw ConfigError(fmt::format("{}: line {}: key '{}' given twice (only one value can be used)", path,
                                    kv.first.Mark().line + 1, here));
    }
    check_unique_keys_at(kv.second, path, here, visited);
  }
}
}  // namespace

void check_unique_keys(const YAML::Node& node, const std::string& path) {
  Visited visited;
  check_unique_keys_at(node, path, "", visited);
}

namespace detail {
std::string yaml_node_text(const YAML::Node& n) {
  if (n.IsScalar()) return fmt::format("'{}'", n.Scalar());
  if (n.IsSequence()) return "a list";
  if (n.IsMap()) return "a mapping";
  return "null";
}
}  // namespace detail

YamlMap::YamlMap(YAML::Node node, std::string where)
    : node_(std::move(node)), where_(std::move(where)), file_(where_) {
  if (node_ && !node_.IsNull() && !node_.IsMap()) {
    throw ConfigError(fmt::format("{}: expected a mapping", where_));
  }
}

std::string YamlMap::path_of(const std::string& key) const { return key; }

bool YamlMap::has(const std::string& key) const { return node_ && node_.IsMap() && node_[key]; }

YamlMap YamlMap::child(const std::string& key) {
  YamlMap out(YAML::Node(YAML::NodeType::Map), where_ + "/" + key);
  out.file_ = file_;
  if (!has(key)) return out;
  used_.insert(key);
  const YAML::Node sub = node_[key];
  if (!sub.IsMap()) throw ConfigError(fmt::format("{}: '{}' must be a mapping", where_, key));
  out.node_ = sub;
  return out;
}

void YamlMap::get_matrix(const std::string& key, Eigen::Ref<Eigen::MatrixXd> value) {
  if (!has(key)) return;
  used_.insert(key);
  const YAML::Node n = node_[key];
  std::vector<double> flat;
  try {
    // Accept a flat list, a list of rows, or an OpenCV-style {rows, cols, data} mapping.
    const YAML::Node data = n.IsMap() && n["data"] ? n["data"] : n;
    if (!data.IsSequence()) throw ConfigError(fmt::format("{}: '{}' must be a list of numbers", where_, key));
    for (const auto& item : data) {
      if (item.IsSequence()) {
        for (const auto& x : item) flat.push_back(x.as<double>());
      } else {
        flat.push_back(item.as<double>());
      }
    }
  } catch (const YAML::Exception& e) {
    throw ConfigError(fmt::format("{}: cannot read '{}' as numbers ({})", where_, key, e.msg));
  }
  if (static_cast<Eigen::Index>(flat.size()) != value.size()) {
    throw ConfigError(fmt::format("{}: '{}' has {} numbers, expected {} ({}x{})", where_, key, flat.size(),
                                  value.size(), value.rows(), value.cols()));
  }
  for (double x : flat) {
    if (!std::isfinite(x)) throw ConfigError(fmt::format("{}: '{}' contains a non-finite number", where_, key));
  }
  for (Eigen::Index r = 0; r < value.rows(); ++r)
    for (Eigen::Index c = 0; c < value.cols(); ++c) value(r, c) = flat[static_cast<size_t>(r * value.cols() + c)];
}

void YamlMap::finish() const {
  if (!node_ || !node_.IsMap()) return;
  for (const auto& kv : node_) {
    // A key that is a list, a mapping or null (`? [a, b]: c`, `~: c`) is never one we read.
    if (!kv.first.IsScalar()) {
      const char* kind = kv.first.IsSequence() ? "list" : kv.first.IsMap() ? "mapping" : "null";
      throw ConfigError(fmt::format("{}: unknown key (a {} at line {})", where_, kind, kv.first.Mark().line + 1));
    }
    const std::string& key = kv.first.Scalar();
    if (!used_.count(key)) throw ConfigError(fmt::format("{}: unknown key '{}'", where_, key));
  }
}

void require_bound(bool ok, const std::string& where, const std::string& key, double value,
                   const std::string& bound) {
  if (!ok) throw ConfigError(fmt::format("{}: {} = {} must be {}", where, key, value, bound));
}

}  // namespace rtslam
