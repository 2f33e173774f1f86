#pragma once
// A FIFO queue in one contiguous buffer that is reused: push_back and pop_front allocate nothing once the buffer
// has grown to the largest number of elements ever held (it doubles when full). std::deque, by contrast, allocates
// and frees a chunk every few elements as a queue slides through it, which the per-frame path must not do.
#include <cstddef>
#include <utility>
#include <vector>

#include "rtslam/core/error.hpp"

namespace rtslam {

template <class T>
class RingBuffer {
 public:
  explicit RingBuffer(std::size_t capacity = 16) : buf_(capacity > 0 ? capacity : 1) {}

  bool empty() const { return size_ == 0; }
  std::size_t size() const { return size_; }
  std::size_t capacity() const { return buf_.size(); }

  void push_back(T v) {
    if (size_ == buf_.size()) grow();
    buf_[(head_ + size_) % buf_.size()] = std::move(v);
    ++size_;
  }
  void pop_front() {
    RTSLAM_CHECK(size_ > 0, "RingBuffer::pop_front on an empty buffer");
    buf_[head_] = T{};  // releases what the element holds (an image) now, not when its slot is reused
    head_ = (head_ + 1) % buf_.size();
    --size_;
  }
  const T& front() const {
    RTSLAM_CHECK(size_ > 0, "RingBuffer::front on an empty buffer");
    return buf_[head_];
  }
  T& front() {
    RTSLAM_CHECK(size_ > 0, "RingBuffer::front on an empty buffer");
    return buf_[head_];
  }
  const T& back() const {
    RTSLAM_CHECK(size_ > 0, "RingBuffer::back on an empty buffer");
    return buf_[(head_ + size_ - 1) % buf_.size()];
  }
  /// The i-th element from the front.
  const T& operator[](std::size_t i) const {
    RTSLAM_CHECK(i < size_, "RingBuffer: index out of range");
    return buf_[(head_ + i) % buf_.size()];
  }
  void clear() {
    while (size_ > 0) pop_front();
    head_ = 0;
    size_ = 0;
  }

 private:
  void grow() {
    std::vector<T> next(2 * buf_.size());
    for (std::size_t i = 0; i < size_; ++i) next[i] = std::move(buf_[(head_ + i) % buf_.size()]);
    buf_ = std::move(next);
    head_ = 0;
  }

  std::vector<T> buf_;
  std::size_t head_ = 0;
  std::size_t size_ = 0;
};

}  // namespace rtslam
