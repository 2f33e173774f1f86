// The filter → viewer channels (latest_queue.hpp): a bounded queue that keeps the newest items and never waits
// for its consumer, the history ring, the doorbell.
#include <atomic>
#include <chrono>
#include <future>
#include <memory>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "rtslam/viz/latest_queue.hpp"

namespace {

using rtslam::viz::Doorbell;
using rtslam::viz::LatestQueue;
using rtslam::viz::SpscRing;

TEST(LatestQueue, KeepsTheNewestAndCountsTheDroppedOldest) {
  LatestQueue<int> q(4);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(q.push(i)) << "room for " << i;
  for (int i = 4; i < 10; ++i) EXPECT_FALSE(q.push(i)) << "full: the oldest goes for " << i;
  EXPECT_EQ(q.pushed(), 10);
  EXPECT_EQ(q.dropped(), 6);
  for (int want = 6; want < 10; ++want) {
    const auto v = q.try_pop();
    ASSERT_TRUE(v.has_value());
    EXPECT_EQ(*v, want);
  }
  EXPECT_FALSE(q.try_pop().has_value());
}

TEST(LatestQueue, CapacityOneIsAMailboxOfTheLatest) {
  LatestQueue<std::unique_ptr<int>> q(1);
  q.push(std::make_unique<int>(1));
  q.push(std::make_unique<int>(2));
  const auto v = q.try_pop();
  ASSERT_TRUE(v && *v);
  EXPECT_EQ(**v, 2);
  EXPECT_EQ(q.dropped(), 1);
}

TEST(LatestQueue, PushNeverWaitsForAConsumerStuckInItsWork) {
  // The consumer takes one item and then hangs "processing" it until the producer is done: if push() waited for
  // the consumer in any way, this test would never end.
  LatestQueue<std::vector<int>> q(3);
  std::promise<void> producer_done;
  std::shared_future<void> done = producer_done.get_future().share();
  std::atomic<bool> took{false};
  std::thread consumer([&] {
    while (!q.try_pop()) std::this_thread::yield();
    took = true;
    done.wait();  // stuck until the producer has pushed everything
  });
  q.push(std::vector<int>(10, 0));
  while (!took) std::this_thread::yield();
  for (int i = 0; i < 100000; ++i) q.push(std::vector<int>(10, i));
  producer_done.set_value();
  consumer.join();
  EXPECT_EQ(q.pushed(), 100001);
  EXPECT_EQ(q.dropped(), 100001 - 1 - 3) << "all but the one taken and the 3 newest";
  int last = -1;
  while (auto v = q.try_pop()) last = v->front();
  EXPECT_EQ(last, 99999);
}

TEST(LatestQueue, ConcurrentConsumerGetsItemsInOrderAndAccountsForEveryOne) {
  LatestQueue<long> q(4);
  constexpr long kN = 200000;
  std::atomic<bool> end{false};
  long delivered = 0, previous = -1;
  bool ordered = true;
  std::thread consumer([&] {
    for (;;) {
      auto v = q.pop_for(std::chrono::milliseconds(1));
      if (v) {
        ordered = ordered && *v > previous;
        previous = *v;
        ++delivered;
      } else if (end) {
        while (auto w = q.try_pop()) {
          ordered = ordered && *w > previous;
          previous = *w;
          ++delivered;
        }
        return;
      }
    }
  });
  for (long i = 0; i < kN; ++i) q.push(i);
  end = true;
  consumer.join();
  EXPECT_TRUE(ordered);
  EXPECT_EQ(previous, kN - 1) << "the newest item is always delivered";
  EXPECT_EQ(delivered + q.dropped() + static_cast<long>(q.waiting()), kN)
      << "each item is delivered, counted as dropped, or still in a slot (overtaken)";
}

TEST(LatestQueue, WakeEndsAWaitWithoutAnItem) {
  LatestQueue<int> q(2);
  std::thread waker([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    q.wake();
  });
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(q.pop_for(std::chrono::seconds(30)).has_value());
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(20));
  waker.join();
}

// The viewer thread reads wakes() before handing batches to the pages' senders: a sender done in between must end
// the next wait at once, not after its 100 ms.
TEST(LatestQueue, AWakeAfterTheCountWasReadIsNotMissed) {
  LatestQueue<int> q(2);
  const std::uint32_t seen = q.wakes();
  q.wake();  // before the wait begins
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(q.pop_for(std::chrono::seconds(30), seen).has_value());
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(20));
  // With the count read after the wake, the wait is a real one (here a short one).
  const auto t1 = std::chrono::steady_clock::now();
  EXPECT_FALSE(q.pop_for(std::chrono::milliseconds(50), q.wakes()).has_value());
  EXPECT_GE(std::chrono::steady_clock::now() - t1, std::chrono::milliseconds(40));
}

TEST(SpscRing, DeliversInOrderAndDropsTheNewWhenFull) {
  SpscRing<int> r(3);
  for (int i = 0; i < 5; ++i) r.push(i);
  EXPECT_EQ(r.dropped(), 2);
  std::vector<int> out;
  r.drain(out);
  EXPECT_EQ(out, (std::vector<int>{0, 1, 2}));
  r.push(7);
  r.drain(out);
  EXPECT_EQ(out.back(), 7);
}

TEST(Doorbell, ARingBeforeTheWaitIsNotMissed) {
  Doorbell b;
  const auto seen = b.count();
  b.ring();
  const auto t0 = std::chrono::steady_clock::now();
  b.wait(seen, std::chrono::seconds(30));
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(20));
}

}  // namespace
