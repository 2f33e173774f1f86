#pragma once
// Small text helpers shared by the io readers and writers: exact number parsing/formatting and line reading.
// Numbers are written with std::to_chars (shortest text that reads back to the same double) and read with
// std::from_chars, so that what a writer writes a reader reads back bit-identically.
#include <cstdint>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

#include "rtslam/core/time.hpp"

namespace rtslam::io {

/// ASCII lower case ("EuRoC" -> "euroc"): file extensions, YAML model names.
std::string to_lower(std::string_view s);

/// Removes leading/trailing spaces, tabs and '\r'.
std::string_view trim(std::string_view s);

/// Splits on `delim` (trimming each field). With delim == ' ' splits on any run of spaces/tabs (no empty fields).
std::vector<std::string_view> split(std::string_view line, char delim);

/// Parses the whole field as a double (accepts "nan", "inf"); false if anything is left over or it is empty.
bool parse_double(std::string_view s, double& value);

/// Parses the whole field as a signed 64-bit integer.
bool parse_int64(std::string_view s, std::int64_t& value);

/// Parses a time in seconds ("1403715273.262142976", "12", "-0.5", "1.2e3") into ns. Decimal notation is converted
/// exactly (digits beyond the 9th decimal are rounded), so nanosecond timestamps survive a text round trip.
bool parse_seconds(std::string_view s, TimeNs& t);

/// Shortest round-trip text of a double ("0.1", "1e-05", "nan").
std::string format_double(double value);

/// Seconds with exactly 9 decimals from integer ns ("1403715273.262142976"), exact for every int64.
std::string format_seconds(TimeNs t);

/// Reads a text file line by line, counting lines (1-based) and stripping a trailing '\r'.
class LineReader {
 public:
  /// Throws IoError naming the file if it cannot be opened.
  explicit LineReader(const std::string& path);
  bool next(std::string& line);
  int line_number() const { return line_; }
  const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::ifstream in_;
  int line_ = 0;
};

/// Opens a file for writing (creating it / truncating); throws IoError naming the file on failure.
std::ofstream open_for_writing(const std::string& path);

/// Flushes and closes; throws IoError naming the file if anything failed while writing.
void close_checked(std::ofstream& out, const std::string& path);

}  // namespace rtslam::io
