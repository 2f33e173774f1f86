// Fuzz target: the strict YAML reader behind every options struct (core/yaml.hpp): load_yaml_file, then a walk of
// the document through YamlMap the way from_yaml() functions read it — typed getters on scalars and lists
// (int, int64, uint64, double, bool, string, vectors), child() on mappings, get_matrix() on lists, require() and
// finish(). Each call may throw ConfigError/IoError naming the file; nothing else.
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "fuzz_util.hpp"
#include "rtslam/core/yaml.hpp"

namespace {

using rtslam::YamlMap;
using rtslam::fuzz::expect_typed_errors;

std::string g_path;

template <class T>
void try_get(YamlMap& m, const std::string& key, const char* call) {
  expect_typed_errors(call, g_path, [&] {
    T value{};
    m.get(key, value);
  });
}

void walk(YamlMap& m, int depth) {
  if (!m.node().IsMap()) return;
  // Keys first (a walk must not change the node while iterating it).
  std::vector<std::string> keys;
  for (const auto& kv : m.node()) {
    if (kv.first.IsScalar()) keys.push_back(kv.first.Scalar());
  }
  for (const auto& key : keys) {
    const YAML::Node value = m.node()[key];
    if (value.IsMap() && depth < 6) {
      expect_typed_errors("YamlMap::child", g_path, [&] {
        YamlMap sub = m.child(key);
        walk(sub, depth + 1);
        sub.finish();
      });
      continue;
    }
    if (value.IsSequence()) {
      try_get<std::vector<double>>(m, key, "YamlMap::get<vector<double>>");
      try_get<std::vector<int>>(m, key, "YamlMap::get<vector<int>>");
      try_get<std::vector<std::string>>(m, key, "YamlMap::get<vector<string>>");
      expect_typed_errors("YamlMap::get_matrix", g_path, [&] {
        Eigen::Matrix4d T;
        m.get_matrix(key, T);
      });
      expect_typed_errors("YamlMap::get_matrix", g_path, [&] {
        Eigen::VectorXd v(static_cast<Eigen::Index>(value.size() % 8));
        m.get_matrix(key, v);
      });
    }
    try_get<int>(m, key, "YamlMap::get<int>");
    try_get<std::int64_t>(m, key, "YamlMap::get<int64>");
    try_get<std::uint64_t>(m, key, "YamlMap::get<uint64>");
    try_get<double>(m, key, "YamlMap::get<double>");
    try_get<bool>(m, key, "YamlMap::get<bool>");
    try_get<std::string>(m, key, "YamlMap::get<string>");
    expect_typed_errors("YamlMap::require<double>", g_path, [&] { (void)m.require<double>(key); });
    expect_typed_errors("YamlMap::child", g_path, [&] { (void)m.child(key); });
  }
  expect_typed_errors("YamlMap::require (missing key)", g_path, [&] { (void)m.require<int>("no such key"); });
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rtslam::fuzz::quiet_logs();
  g_path = rtslam::fuzz::write_input("config.yaml", "");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  rtslam::fuzz::write_input("config.yaml", data, size);
  YAML::Node root;
  if (!expect_typed_errors("load_yaml_file", g_path, [&] { root = rtslam::load_yaml_file(g_path); })) return 0;
  expect_typed_errors("YamlMap", g_path, [&] {
    YamlMap top(root, g_path);
    walk(top, 0);
    top.finish();
  });
  return 0;
}
