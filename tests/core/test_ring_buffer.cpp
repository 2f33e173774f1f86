// The FIFO ring buffer against std::deque on a long random sequence of pushes and pops, across its growth.
#include <gtest/gtest.h>

#include <deque>
#include <random>

#include "rtslam/core/error.hpp"
#include "rtslam/core/ring_buffer.hpp"

namespace rtslam {
namespace {

TEST(RingBuffer, BehavesLikeADequeAcrossWrapAndGrowth) {
  RingBuffer<int> rb(2);
  std::deque<int> ref;
  std::mt19937 rng(7);
  int next = 0;
  for (int step = 0; step < 20000; ++step) {
    // Phases that fill (growth) and drain (wrap-around) the buffer.
    const bool push = ref.empty() || (rng() % 100) < ((step / 2000) % 2 == 0 ? 70u : 35u);
    if (push) {
      rb.push_back(next);
      ref.push_back(next);
      ++next;
    } else {
      ASSERT_EQ(rb.front(), ref.front());
      rb.pop_front();
      ref.pop_front();
    }
    ASSERT_EQ(rb.size(), ref.size());
    if (!ref.empty()) {
      ASSERT_EQ(rb.front(), ref.front());
      ASSERT_EQ(rb.back(), ref.back());
      const std::size_t i = rng() % ref.size();
      ASSERT_EQ(rb[i], ref[i]);
    }
  }
}

TEST(RingBuffer, KeepsItsCapacityOnceGrown) {
  RingBuffer<int> rb(4);
  for (int i = 0; i < 10; ++i) rb.push_back(i);
  const std::size_t cap = rb.capacity();
  EXPECT_GE(cap, 10u);
  // A sliding window of at most 10 elements never grows it again.
  for (int i = 10; i < 10000; ++i) {
    rb.pop_front();
    rb.push_back(i);
  }
  EXPECT_EQ(rb.capacity(), cap);
  EXPECT_EQ(rb.front(), 9990);
  rb.clear();
  EXPECT_TRUE(rb.empty());
  EXPECT_THROW(rb.pop_front(), Error);
}

}  // namespace
}  // namespace rtslam
