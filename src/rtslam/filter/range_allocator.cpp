#include "rtslam/filter/range_allocator.hpp"

#include <algorithm>

#include "rtslam/core/error.hpp"

namespace rtslam::filter {

RangeAllocator::RangeAllocator(int capacity) : capacity_(capacity) {
  RTSLAM_CHECK(capacity > 0, "capacity must be positive");
  // Free intervals are disjoint and non-adjacent: at most (capacity + 1) / 2 of them, so releases never allocate.
  free_.reserve(static_cast<std::size_t>(capacity + 1) / 2 + 1);
  free_.push_back({0, capacity});
}

std::optional<int> RangeAllocator::allocate(int size) {
  RTSLAM_CHECK(size > 0, "allocation size must be positive");
  for (auto it = free_.begin(); it != free_.end(); ++it) {
    if (it->end - it->begin >= size) {
      const int offset = it->begin;
      it->begin += size;
      if (it->begin == it->end) free_.erase(it);
      return offset;
    }
  }
  return std::nullopt;
}

void RangeAllocator::release(int offset, int size) {
  RTSLAM_CHECK(offset >= 0 && size > 0 && offset + size <= capacity_, "release out of range");
  const Interval r{offset, offset + size};
  auto it = std::lower_bound(free_.begin(), free_.end(), r, [](const Interval& a, const Interval& b) {
    return a.begin < b.begin;
  });
  RTSLAM_CHECK(it == free_.end() || r.end <= it->begin, "double release (overlaps the next free range)");
  RTSLAM_CHECK(it == free_.begin() || std::prev(it)->end <= r.begin, "double release (overlaps the previous one)");
  it = free_.insert(it, r);
  // Merge with the next, then with the previous.
  if (std::next(it) != free_.end() && std::next(it)->begin == it->end) {
    it->end = std::next(it)->end;
    free_.erase(std::next(it));
  }
  if (it != free_.begin() && std::prev(it)->end == it->begin) {
    std::prev(it)->end = it->end;
    free_.erase(it);
  }
}

int RangeAllocator::free_total() const {
  int s = 0;
  for (const auto& f : free_) s += f.end - f.begin;
  return s;
}

int RangeAllocator::largest_free() const {
  int s = 0;
  for (const auto& f : free_) s = std::max(s, f.end - f.begin);
  return s;
}

}  // namespace rtslam::filter
