#pragma once
// Time inside rtslam is an int64 count of nanoseconds (EuRoC style); seconds as double only at I/O.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>

namespace rtslam {

using TimeNs = std::int64_t;

constexpr TimeNs kNsPerSecond = 1'000'000'000;
constexpr TimeNs kNsPerMs = 1'000'000;

/// Nanoseconds -> seconds (for I/O and for dt in models).
constexpr double to_seconds(TimeNs t) { return static_cast<double>(t) * 1e-9; }

/// Seconds -> nanoseconds, rounded to the nearest nanosecond. s must be finite and within ±9.2e9 s (use
/// from_seconds_checked for values that come from outside).
inline TimeNs from_seconds(double s) { return static_cast<TimeNs>(std::llround(s * 1e9)); }

/// Largest |seconds| whose nanoseconds fit int64 with room to spare (int64 holds ±9.22e9 s).
constexpr double kMaxTimeSeconds = 9.2e9;

/// Seconds -> nanoseconds, or nullopt when s is not finite or the result would not fit int64.
inline std::optional<TimeNs> from_seconds_checked(double s) {
  if (!std::isfinite(s) || std::abs(s) > kMaxTimeSeconds) return std::nullopt;
  return from_seconds(s);
}

/// a + b, or nullopt when the sum overflows int64 (time arithmetic on values from files).
inline std::optional<TimeNs> add_checked(TimeNs a, TimeNs b) {
  TimeNs out = 0;
  if (__builtin_add_overflow(a, b, &out)) return std::nullopt;
  return out;
}

/// a * b for sizes (pixel counts, buffer lengths), or nullopt on overflow of std::size_t.
inline std::optional<std::size_t> mul_checked(std::size_t a, std::size_t b) {
  std::size_t out = 0;
  if (__builtin_mul_overflow(a, b, &out)) return std::nullopt;
  return out;
}

}  // namespace rtslam
