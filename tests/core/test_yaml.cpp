// Config reading (core/yaml.hpp) and checked time arithmetic (core/time.hpp): every error names the file, the key
// path, the value and what it must be; no value from a file overflows an int64 time.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <limits>

#include <sys/stat.h>

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

TEST(LoadYamlFile, AKeyGivenTwiceIsAnErrorNamingLineAndKeyPath) {
  // Review 27 Nov: yaml-cpp keeps both, a lookup sees the first, and the second was ignored silently.
  const auto path = (std::filesystem::temp_directory_path() / "rtslam_test_dup_keys.yaml").string();
  {
    std::ofstream out(path);
    out << "search:\n  sigma_px: 0.5\n  grid: {cells_x: 4}\n  sigma_px: 200\n";
  }
  EXPECT_EQ(message_of([&] { load_yaml_file(path); }),
            path + ": line 4: key 'search/sigma_px' given twice (only one value can be used)");
  {
    std::ofstream out(path);
    out << "slam: {seed: 1}\nlist:\n  - {a: 1, a: 2}\nslam: {seed: 2}\n";
  }
  EXPECT_EQ(message_of([&] { load_yaml_file(path); }),
            path + ": line 3: key 'list[0]/a' given twice (only one value can be used)");
  {
    std::ofstream out(path);
    out << "a: {x: 1}\nb: {x: 2}\n";  // the same key in two mappings is fine
  }
  EXPECT_TRUE(load_yaml_file(path).IsMap());
  std::filesystem::remove(path);
}

TEST(LoadYamlFile, APipeIsAnErrorNotAHang) {
  // Review 27 Nov: --config pointing at a FIFO with no writer blocked the run until killed.
  const auto path = (std::filesystem::temp_directory_path() / "rtslam_test_fifo.yaml").string();
  std::filesystem::remove(path);
  ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0);
  EXPECT_EQ(message_of([&] { load_yaml_file(path); }),
            path + ": not a regular file (a pipe or device), not a YAML file");
  std::filesystem::remove(path);
}

TEST(LoadYamlFile, AliasesAreCheckedOnceNotPerReference) {
  // Review 27 Nov: the duplicate-key walk followed aliases: nested ones made it exponential, a self-reference endless.
  const auto path = (std::filesystem::temp_directory_path() / "rtslam_test_aliases.yaml").string();
  {
    std::ofstream out(path);
    out << "l0: &a0 [x, y]\n";
    for (int i = 1; i <= 40; ++i) out << "l" << i << ": &a" << i << " [*a" << i - 1 << ", *a" << i - 1 << "]\n";
  }
  EXPECT_TRUE(load_yaml_file(path).IsMap());  // 2^40 paths, 41 lists
  {
    std::ofstream out(path);
    out << "a: &m {k: 1, k2: *m}\nb: [*m, *m]\n";
  }
  try {
    load_yaml_file(path);  // yaml-cpp may refuse the cycle; it must not hang or overflow
  } catch (const Error&) {
  }
  {
    std::ofstream out(path);
    out << "a: &m {k: 1, k: 2}\nb: *m\n";
  }
  EXPECT_EQ(message_of([&] { load_yaml_file(path); }),
            path + ": line 1: key 'a/k' given twice (only one value can be used)");
  std::filesystem::remove(path);
}

TEST(LoadYamlFile, AFileWithNoSettingsIsAnError) {
  const auto path = (std::filesystem::temp_directory_path() / "rtslam_test_empty.yaml").string();
  for (const char* text : {"", "# only a comment\n\n"}) {
    {
      std::ofstream out(path);
      out << text;
    }
    EXPECT_EQ(message_of([&] { load_yaml_file(path); }), path + ": no settings in the file (empty, or only comments)");
  }
  std::filesystem::remove(path);
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
