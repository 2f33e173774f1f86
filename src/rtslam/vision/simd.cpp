#include "rtslam/vision/simd.hpp"

#include <atomic>

namespace rtslam::vision {

namespace {

SimdLevel detect() {
#if defined(__x86_64__)
  // __builtin_cpu_supports also checks that the OS saves the AVX registers; __builtin_cpu_init makes it usable even
  // from static initializers.
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") ? SimdLevel::avx2 : SimdLevel::sse2;
#else
  return SimdLevel::scalar;
#endif
}

std::atomic<SimdLevel>& current() {
  static std::atomic<SimdLevel> level{best_simd_level()};
  return level;
}

}  // namespace

SimdLevel best_simd_level() {
  static const SimdLevel best = detect();
  return best;
}

SimdLevel simd_level() { return current().load(std::memory_order_relaxed); }

SimdLevel set_simd_level(SimdLevel level) {
  const SimdLevel used = static_cast<int>(level) < static_cast<int>(best_simd_level()) ? level : best_simd_level();
  current().store(used, std::memory_order_relaxed);
  return used;
}

const char* to_string(SimdLevel level) {
  switch (level) {
    case SimdLevel::scalar:
      return "scalar";
    case SimdLevel::sse2:
      return "sse2";
    case SimdLevel::avx2:
      return "avx2";
  }
  return "unknown";
}

}  // namespace rtslam::vision
