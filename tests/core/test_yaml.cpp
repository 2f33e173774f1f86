// Config reading (core/yaml.hpp) and checked time arithmetic (core/time.hpp): every error names the file, the key
// path, the value and what it must be; no value from a file overflows an int64 time.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>

#include "rtslam/core/error.hpp"
#include "rtslam/core/time.hpp"
#include "rtslam/core/yaml.hpp"

namespace rtslam {
namespace {

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(YamlMap, ABadConversionNamesFileKeyPathValueAndType) {
  YamlMap top(YAML::Load("search:\n  max_inits: 1e10\n  grid: {cells_x: abc}\n"), "my.yaml");
  YamlMap s = top.child("search");
  int n = 0;
  EXPECT_EQ(message_of([&] { s.get("max_inits", n); }),
            "my.yaml/search: max_inits = '1e10' must be an integer in [-2147483648, 2147483647]");
  YamlMap g = s.child("grid");
  EXPECT_EQ(g.file(), "my.yaml");
  EXPECT_EQ(message_of([&] { g.get("cells_x", n); }),
            "my.yaml/search/grid: cells_x = 'abc' must be an integer in [-2147483648, 2147483647]");
  bool b = false;
  YamlMap t(YAML::Load("flag: [1, 2]\n"), "f.yaml");
  EXPECT_EQ(message_of([&] { t.get("flag", b); }), "f.yaml: flag = a list must be true or false");
}

TEST(YamlMap, ValidateInFileAddsTheFileToABoundError) {
  EXPECT_EQ(message_of([] { validate_in_file("c.yaml", [] { require_bound(false, "search", "n_sigma", 50, "in (0, 10]"); }); }),
            "c.yaml: search: n_sigma = 50 must be in (0, 10]");
}

TEST(LoadYamlFile, ADirectoryIsOneIoErrorNamingIt) {
  const auto dir = std::filesystem::temp_directory_path();
  EXPECT_EQ(message_of([&] { load_yaml_file(dir.string()); }), dir.string() + ": is a directory, not a YAML file");
}

TEST(CheckedTime, SecondsBeyondInt64AndOverflowingSumsAreRefused) {
  EXPECT_EQ(from_seconds_checked(1.5), 1'500'000'000);
  EXPECT_FALSE(from_seconds_checked(1e10).has_value());
  EXPECT_FALSE(from_seconds_checked(std::numeric_limits<double>::infinity()).has_value());
  EXPECT_FALSE(from_seconds_checked(std::nan("")).has_value());
  EXPECT_EQ(add_checked(1, 2), 3);
  EXPECT_FALSE(add_checked(std::numeric_limits<TimeNs>::max(), 1).has_value());
  EXPECT_FALSE(mul_checked(std::size_t{1} << 40, std::size_t{1} << 40).has_value());
  EXPECT_EQ(mul_checked(100000, 100000), std::size_t{10'000'000'000});
}

}  // namespace
}  // namespace rtslam
