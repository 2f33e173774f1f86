#pragma once
// Typed errors for configuration, file and data problems. The library throws these; the CLI catches them in
// main and prints one line. The per-frame hot path never throws: expected failures are return values.
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace rtslam {

/// Base of every rtslam error; what() is one line that names the file/key/value and the violated bound.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A configuration key is unknown, missing or out of its bounds.
class ConfigError : public Error {
 public:
  using Error::Error;
};

/// A file is missing, unreadable or malformed.
class IoError : public Error {
 public:
  using Error::Error;
};

/// Input data is inconsistent (timestamps out of order, NaNs, ...).
class DataError : public Error {
 public:
  using Error::Error;
};

/// An internal invariant was violated (a bug, not a user error).
class InvariantError : public Error {
 public:
  using Error::Error;
};

[[noreturn]] void throw_invariant(const char* cond, const char* file, int line, const std::string& msg);

}  // namespace rtslam

/// Always-on invariant check (also in release builds). Use outside the per-frame hot path, or for bugs only.
#define RTSLAM_CHECK(cond, msg)                                         \
  do {                                                                  \
    if (!(cond)) ::rtslam::throw_invariant(#cond, __FILE__, __LINE__, (msg)); \
  } while (false)
