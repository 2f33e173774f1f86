#pragma once
// Shared by the libFuzzer targets (docs/testing.md, "Fuzzing").
//
// What a finding is: the library's contract for bad input is a typed error (IoError, ConfigError, DataError) whose
// message names the file. A target calls the code under test through expect_typed_errors(): a return or one of
// those errors is a normal outcome; any other exception (yaml-cpp's, nlohmann's, std::out_of_range,
// InvariantError, ...) or an error message that does not name the file is reported and aborts, and so does a
// broken post-condition checked with FUZZ_CHECK. Crashes, sanitizer reports (ASan, UBSan: built with
// -fno-sanitize-recover), timeouts and allocations above libFuzzer's limits are findings by themselves.
//
// Loaders that take a path read the input from a per-process scratch folder (write_input), so the path-based API
// and its messages are what gets fuzzed.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "rtslam/core/error.hpp"

namespace rtslam::fuzz {

/// This process's scratch folder (created on first use, removed at exit).
const std::string& scratch_dir();

/// Writes `size` bytes to scratch_dir()/rel (creating parent folders); returns the full path.
std::string write_input(const std::string& rel, const std::uint8_t* data, std::size_t size);
std::string write_input(const std::string& rel, std::string_view text);

/// Prints "fuzz finding: <what>" to stderr and aborts (libFuzzer then saves the input).
[[noreturn]] void finding(const std::string& what);

/// Silences rtslam's loggers (warnings about skipped lines would flood the fuzzer's output).
void quiet_logs();

/// Called in a catch block for an exception that is not a typed error: reports its type and message, aborts.
[[noreturn]] void unexpected_exception(const char* call);

/// Checks a typed error: its message must contain `names` (the file, or a folder the file is in).
void check_message(const Error& e, std::string_view names, const char* call);

/// Runs f(). Returns true if it returned, false if it threw a typed error (IoError, ConfigError, DataError) whose
/// message contains `names`; anything else is a finding (`call` names the call in the report).
template <class F>
bool expect_typed_errors(const char* call, std::string_view names, F&& f) {
  try {
    f();
    return true;
  } catch (const IoError& e) {
    check_message(e, names, call);
  } catch (const ConfigError& e) {
    check_message(e, names, call);
  } catch (const DataError& e) {
    check_message(e, names, call);
  } catch (...) {
    unexpected_exception(call);
  }
  return false;
}

}  // namespace rtslam::fuzz

/// A post-condition of a successful call; a finding if it does not hold.
#define FUZZ_CHECK(cond, msg)                                                                             \
  do {                                                                                                    \
    if (!(cond)) ::rtslam::fuzz::finding(std::string("check '" #cond "' failed: ") + std::string(msg)); \
  } while (false)
