#pragma once
// The two channels from the filter thread (one producer) to the viewer thread (one consumer). Neither ever makes
// the producer wait, nor enters the kernel: no mutex is shared with the consumer (a mutex held by a consumer that
// the scheduler has put aside — the viewer thread runs at a lower priority — would stall the filter for
// milliseconds), and the producer does not wake the consumer either (on a busy machine the woken thread preempts
// the waker: measured 2 ms per push on 2 loaded cores); the consumer polls at its own pace.
//
// LatestQueue<T>: a bounded queue that keeps the NEWEST items. Each item travels as an owned pointer that moves
// only by atomic exchange: the producer exchanges it into slot (n mod capacity); what it takes back is the item
// pushed `capacity` pushes earlier that the consumer has not taken — the oldest waiting — which is dropped and
// counted, and handed back to the consumer to destroy (freeing an image is the consumer's cost too). The consumer
// exchanges slots out in push order (items the producer overtook meanwhile count as dropped).
// SpscRing<T>: a bounded FIFO of values (the per-frame history); when full, the producer drops the new value.
// Doorbell: the consumer sleeps on it with a timeout; other threads ring it (FUTEX_WAKE: never blocks).
#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <ctime>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "rtslam/core/error.hpp"

namespace rtslam::viz {

class Doorbell {
 public:
  /// Wakes a consumer sleeping in wait(). Never blocks.
  void ring() {
    count_.fetch_add(1, std::memory_order_release);
    if (sleeping_.load(std::memory_order_acquire) > 0) {
      ::syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&count_), FUTEX_WAKE_PRIVATE, 1, nullptr, nullptr, 0);
    }
  }
  /// The current count: pass it to wait() after checking for work, so that a ring in between is not missed.
  std::uint32_t count() const { return count_.load(std::memory_order_acquire); }
  /// Sleeps until the count differs from `seen` or `timeout` passes.
  void wait(std::uint32_t seen, std::chrono::nanoseconds timeout) {
    if (timeout.count() <= 0) return;
    timespec ts{};
    ts.tv_sec = static_cast<time_t>(timeout.count() / 1'000'000'000);
    ts.tv_nsec = static_cast<long>(timeout.count() % 1'000'000'000);
    sleeping_.fetch_add(1, std::memory_order_acq_rel);
    if (count_.load(std::memory_order_acquire) == seen) {
      ::syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&count_), FUTEX_WAIT_PRIVATE, seen, &ts, nullptr, 0);
    }
    sleeping_.fetch_sub(1, std::memory_order_acq_rel);
  }

 private:
  static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t), "futex word");
  std::atomic<std::uint32_t> count_{0};
  std::atomic<int> sleeping_{0};
};

template <class T>
class SpscRing {
 public:
  explicit SpscRing(std::size_t capacity) : buf_(capacity) {
    RTSLAM_CHECK(capacity > 0, "SpscRing needs a capacity of at least 1");
  }
  /// Producer. False (and the value is dropped, counted) when the ring is full.
  bool push(const T& v) {
    const std::uint64_t h = head_.load(std::memory_order_relaxed);
    if (h - tail_.load(std::memory_order_acquire) == buf_.size()) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    buf_[h % buf_.size()] = v;
    head_.store(h + 1, std::memory_order_release);
    return true;
  }
  /// Consumer. Appends every value waiting to `out`.
  template <class Out>
  void drain(Out& out) {
    const std::uint64_t h = head_.load(std::memory_order_acquire);
    std::uint64_t t = tail_.load(std::memory_order_relaxed);
    for (; t < h; ++t) out.push_back(std::move(buf_[t % buf_.size()]));
    tail_.store(t, std::memory_order_release);
  }
  long dropped() const { return dropped_.load(std::memory_order_relaxed); }

 private:
  std::vector<T> buf_;
  std::atomic<std::uint64_t> head_{0};
  std::atomic<std::uint64_t> tail_{0};
  std::atomic<long> dropped_{0};
};

template <class T>
class LatestQueue {
 public:
  explicit LatestQueue(std::size_t capacity) : capacity_(capacity) {
    RTSLAM_CHECK(capacity > 0, "LatestQueue needs a capacity of at least 1");
    slots_ = std::make_unique<std::atomic<Item*>[]>(capacity);
    for (std::size_t i = 0; i < capacity; ++i) slots_[i].store(nullptr, std::memory_order_relaxed);
  }
  ~LatestQueue() {
    for (std::size_t i = 0; i < capacity_; ++i) delete slots_[i].exchange(nullptr);
    collect_garbage();
  }
  LatestQueue(const LatestQueue&) = delete;
  LatestQueue& operator=(const LatestQueue&) = delete;

  /// Producer (one thread). Adds `value`; returns false when the oldest waiting item was dropped to make room.
  /// Never waits for the consumer and does not wake it. The dropped item goes back to the consumer for destruction
  /// (destroyed here only if the consumer left 64 of them uncollected).
  bool push(T value) {
    auto* item = new Item{written_local_, std::move(value)};
    Item* old = slots_[written_local_ % capacity_].exchange(item, std::memory_order_acq_rel);
    ++written_local_;
    written_.store(written_local_, std::memory_order_release);
    pushed_.fetch_add(1, std::memory_order_relaxed);
    if (old == nullptr) return true;
    dropped_.fetch_add(1, std::memory_order_relaxed);
    if (!garbage_.push(old)) delete old;
    return false;
  }

  /// Consumer (one thread). The oldest item not yet taken, or nothing.
  std::optional<T> try_pop() {
    collect_garbage();
    const std::uint64_t w = written_.load(std::memory_order_acquire);
    if (read_ + capacity_ < w) read_ = w - capacity_;  // the producer lapped us: those slots hold newer items
    while (read_ < w) {
      Item* p = slots_[read_ % capacity_].exchange(nullptr, std::memory_order_acq_rel);
      if (p == nullptr) {
        ++read_;
        continue;
      }
      if (p->seq < read_) {  // overtaken earlier and skipped: dropped
        dropped_.fetch_add(1, std::memory_order_relaxed);
        delete p;
        ++read_;
        continue;
      }
      read_ = p->seq + 1;
      std::optional<T> out(std::move(p->value));
      delete p;
      return out;
    }
    return std::nullopt;
  }

  /// Consumer: try_pop(), else sleeps up to `timeout` (or until a wake()) and tries again.
  template <class Rep, class Period>
  std::optional<T> pop_for(std::chrono::duration<Rep, Period> timeout) {
    return pop_for(timeout, wakes());
  }
  /// pop_for() that also returns at once if wake() was called since wakes() returned `seen` (read it before looking
  /// for other work, so that a wake() in between is not missed).
  template <class Rep, class Period>
  std::optional<T> pop_for(std::chrono::duration<Rep, Period> timeout, std::uint32_t seen) {
    if (auto v = try_pop()) return v;
    bell_.wait(seen, std::chrono::duration_cast<std::chrono::nanoseconds>(timeout));
    return try_pop();
  }
  std::uint32_t wakes() const { return bell_.count(); }

  /// Wakes the consumer in pop_for without an item (other work to do). Never blocks.
  void wake() { bell_.ring(); }

  std::size_t capacity() const { return capacity_; }
  /// Items in the slots (not yet taken nor dropped; some may be overtaken ones that will count as dropped):
  /// pushed() == items taken + dropped() + waiting() once the producer is quiet.
  std::size_t waiting() const {
    std::size_t n = 0;
    for (std::size_t i = 0; i < capacity_; ++i) n += slots_[i].load(std::memory_order_acquire) != nullptr ? 1 : 0;
    return n;
  }
  long pushed() const { return pushed_.load(std::memory_order_relaxed); }
  long dropped() const { return dropped_.load(std::memory_order_relaxed); }

 private:
  struct Item {
    std::uint64_t seq;
    T value;
  };
  void collect_garbage() {
    garbage_.drain(garbage_out_);
    for (Item* p : garbage_out_) delete p;
    garbage_out_.clear();
  }
  std::size_t capacity_;
  std::unique_ptr<std::atomic<Item*>[]> slots_;
  std::uint64_t written_local_ = 0;          // producer's own count
  std::atomic<std::uint64_t> written_{0};    // published count
  std::uint64_t read_ = 0;                   // consumer's position
  std::atomic<long> pushed_{0};
  std::atomic<long> dropped_{0};
  SpscRing<Item*> garbage_{64};  // dropped items, for the consumer to destroy
  std::vector<Item*> garbage_out_;
  Doorbell bell_;
};

}  // namespace rtslam::viz
