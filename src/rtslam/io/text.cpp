#include "rtslam/io/text.hpp"

#include <algorithm>
#include <cctype>

#include <charconv>
#include <cmath>
#include <filesystem>
#include <limits>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"

namespace rtslam::io {

std::string to_lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(), [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  return out;
}

std::string_view trim(std::string_view s) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\n'; };
  while (!s.empty() && is_space(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_space(s.back())) s.remove_suffix(1);
  return s;
}

std::vector<std::string_view> split(std::string_view line, char delim) {
  std::vector<std::string_view> out;
  if (delim == ' ') {
    size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
      size_t j = i;
      while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
      if (j > i) out.push_back(line.substr(i, j - i));
      i = j;
    }
    return out;
  }
  size_t start = 0;
  while (true) {
    const size_t pos = line.find(delim, start);
    if (pos == std::string_view::npos) {
      out.push_back(trim(line.substr(start)));
      break;
    }
    out.push_back(trim(line.substr(start, pos - start)));
    start = pos + 1;
  }
  return out;
}

bool parse_double(std::string_view s, double& value) {
  s = trim(s);
  if (s.empty()) return false;
  if (s.front() == '+') s.remove_prefix(1);
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ptr != s.data() + s.size()) return false;
  if (ec == std::errc::result_out_of_range) {
    // from_chars leaves v unset on overflow (1e400) and on underflow below the subnormals (1e-400); long double's
    // range (1e±4932) tells them apart, without a locale. An overflow is not a number we can use; an underflow is
    // ±0 (or the nearest subnormal); beyond long double too, refused.
    long double lv = 0.0L;
    const auto [lptr, lec] = std::from_chars(s.data(), s.data() + s.size(), lv);
    if (lec != std::errc() || lptr != s.data() + s.size()) return false;
    if (!(std::fabs(lv) <= static_cast<long double>(std::numeric_limits<double>::max()))) return false;
    value = static_cast<double>(lv);
    return true;
  }
  if (ec != std::errc()) return false;
  value = v;
  return true;
}

bool parse_int64(std::string_view s, std::int64_t& value) {
  s = trim(s);
  if (s.empty()) return false;
  if (s.front() == '+') s.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  return ec == std::errc() && ptr == s.data() + s.size();
}

bool parse_seconds(std::string_view s, TimeNs& t) {
  s = trim(s);
  if (s.empty()) return false;
  const bool plain = s.find_first_of("eEnNiI") == std::string_view::npos;
  if (!plain) {
    double v = 0.0;
    if (!parse_double(s, v) || !std::isfinite(v) || std::abs(v) > 9.2e9) return false;
    t = from_seconds(v);
    return true;
  }
  bool negative = false;
  if (s.front() == '-' || s.front() == '+') {
    negative = s.front() == '-';
    s.remove_prefix(1);
  }
  const size_t dot = s.find('.');
  const std::string_view int_part = s.substr(0, dot);
  std::string_view frac_part = dot == std::string_view::npos ? std::string_view{} : s.substr(dot + 1);
  if (int_part.empty() && frac_part.empty()) return false;
  std::int64_t whole = 0;
  if (!int_part.empty()) {
    if (int_part.size() > 10) return false;  // beyond int64 ns
    for (char c : int_part) {
      if (c < '0' || c > '9') return false;
      whole = whole * 10 + (c - '0');
    }
  }
  std::int64_t frac = 0;
  int digits = 0;
  bool round_up = false;
  for (size_t i = 0; i < frac_part.size(); ++i) {
    const char c = frac_part[i];
    if (c < '0' || c > '9') return false;
    if (digits < 9) {
      frac = frac * 10 + (c - '0');
      ++digits;
    } else if (i == 9) {
      round_up = c >= '5';
    }
  }
  for (; digits < 9; ++digits) frac *= 10;
  // Up to 10 integer digits fit the parse but not always int64 ns (max ~9.22e9 s): out of range is not a time.
  std::int64_t ns = 0;
  if (__builtin_mul_overflow(whole, kNsPerSecond, &ns) || __builtin_add_overflow(ns, frac + (round_up ? 1 : 0), &ns)) {
    return false;
  }
  t = negative ? -ns : ns;
  return true;
}

std::string format_double(double value) {
  char buf[64];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), value);
  if (ec != std::errc()) return fmt::format("{}", value);
  return std::string(buf, ptr);
}

std::string format_seconds(TimeNs t) {
  const bool negative = t < 0;
  // Work in unsigned to survive INT64_MIN.
  const std::uint64_t mag = negative ? 0ULL - static_cast<std::uint64_t>(t) : static_cast<std::uint64_t>(t);
  return fmt::format("{}{}.{:09d}", negative ? "-" : "", mag / 1'000'000'000ULL, mag % 1'000'000'000ULL);
}

LineReader::LineReader(const std::string& path) : path_(path) {
  // Checked before opening: opening a FIFO (or a device) for reading blocks until someone writes to it.
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw IoError(fmt::format("{}: file not found", path));
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw IoError(fmt::format("{}: not a regular file (a directory, pipe or device)", path));
  }
  in_.open(path);
  if (!in_) throw IoError(fmt::format("{}: cannot open for reading", path));
}

bool LineReader::next(std::string& line) {
  if (!std::getline(in_, line)) return false;
  ++line_;
  if (!line.empty() && line.back() == '\r') line.pop_back();
  // A UTF-8 byte-order mark (files saved by some Windows editors) is not part of the first line.
  if (line_ == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
  return true;
}

std::ofstream open_for_writing(const std::string& path) {
  std::ofstream out(path, std::ios::out | std::ios::trunc);
  if (!out) throw IoError(fmt::format("{}: cannot open for writing", path));
  return out;
}

void close_checked(std::ofstream& out, const std::string& path) {
  out.flush();
  if (!out) throw IoError(fmt::format("{}: write failed", path));
  out.close();
}

}  // namespace rtslam::io
