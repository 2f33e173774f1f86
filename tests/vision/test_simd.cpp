#include <gtest/gtest.h>

#include <string>

#include "rtslam/vision/simd.hpp"
#include "vision_test_utils.hpp"

using namespace rtslam::vision;

TEST(SimdLevel, StartsAtTheBestLevelAndClampsRequestsToIt) {
  EXPECT_EQ(simd_level(), best_simd_level());
#if defined(__x86_64__)
  EXPECT_GE(static_cast<int>(best_simd_level()), static_cast<int>(SimdLevel::sse2));  // SSE2 is the x86-64 baseline
#endif
  {
    test::ScopedSimdLevel scalar(SimdLevel::scalar);
    EXPECT_EQ(simd_level(), SimdLevel::scalar);
  }
  EXPECT_EQ(simd_level(), best_simd_level());
  EXPECT_EQ(set_simd_level(SimdLevel::avx2), best_simd_level());  // never above what the CPU runs
  EXPECT_EQ(std::string(to_string(SimdLevel::scalar)), "scalar");
  EXPECT_EQ(std::string(to_string(SimdLevel::sse2)), "sse2");
  EXPECT_EQ(std::string(to_string(SimdLevel::avx2)), "avx2");
}
