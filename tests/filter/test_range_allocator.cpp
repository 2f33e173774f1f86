#include "rtslam/filter/range_allocator.hpp"

#include <gtest/gtest.h>

namespace rtslam::filter {
namespace {

TEST(RangeAllocator, FirstFitAndReuseOfFreedRanges) {
  RangeAllocator a(20);
  EXPECT_EQ(a.allocate(7), 0);
  EXPECT_EQ(a.allocate(3), 7);
  EXPECT_EQ(a.allocate(7), 10);
  EXPECT_EQ(a.free_total(), 3);
  EXPECT_FALSE(a.allocate(4).has_value());
  a.release(0, 7);
  EXPECT_EQ(a.allocate(3), 0);  // a freed 7-range takes a 3-block first (first fit)
  EXPECT_EQ(a.allocate(4), 3);
  EXPECT_EQ(a.free_total(), 3);
}

TEST(RangeAllocator, MergesNeighboursOnRelease) {
  RangeAllocator a(12);
  ASSERT_EQ(a.allocate(4), 0);
  ASSERT_EQ(a.allocate(4), 4);
  ASSERT_EQ(a.allocate(4), 8);
  a.release(0, 4);
  a.release(8, 4);
  EXPECT_EQ(a.largest_free(), 4);
  a.release(4, 4);
  EXPECT_EQ(a.largest_free(), 12);
  EXPECT_EQ(a.allocate(12), 0);
}

TEST(RangeAllocator, DoubleReleaseIsAnInvariantError) {
  RangeAllocator a(8);
  ASSERT_EQ(a.allocate(4), 0);
  a.release(0, 4);
  EXPECT_ANY_THROW(a.release(0, 4));
}

}  // namespace
}  // namespace rtslam::filter
