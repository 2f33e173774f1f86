#pragma once
// First-fit allocator of contiguous index ranges in [0, capacity): the free space of the state vector and of the
// covariance. Freed ranges merge with their neighbours and are reused. Not used per frame (only when blocks are
// added or removed), so a sorted vector of free intervals is enough.
#include <optional>
#include <vector>

namespace rtslam::filter {

class RangeAllocator {
 public:
  explicit RangeAllocator(int capacity);
  /// Offset of a free range of `size`, lowest first (first fit); nullopt if no contiguous room.
  std::optional<int> allocate(int size);
  void release(int offset, int size);
  int capacity() const { return capacity_; }
  int free_total() const;
  int largest_free() const;

 private:
  struct Interval {
    int begin;
    int end;  // exclusive
  };
  int capacity_;
  std::vector<Interval> free_;  // sorted, disjoint, non-adjacent
};

}  // namespace rtslam::filter
