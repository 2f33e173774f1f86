#pragma once
// Time inside rtslam is an int64 count of nanoseconds (EuRoC style); seconds as double only at I/O.
#include <cmath>
#include <cstdint>

namespace rtslam {

using TimeNs = std::int64_t;

constexpr TimeNs kNsPerSecond = 1'000'000'000;

/// Nanoseconds -> seconds (for I/O and for dt in models).
constexpr double to_seconds(TimeNs t) { return static_cast<double>(t) * 1e-9; }

/// Seconds -> nanoseconds, rounded to the nearest nanosecond.
inline TimeNs from_seconds(double s) { return static_cast<TimeNs>(std::llround(s * 1e9)); }

}  // namespace rtslam
