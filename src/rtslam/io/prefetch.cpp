#include "rtslam/io/prefetch.hpp"

#include <algorithm>
#include <chrono>
#include <utility>

#include "rtslam/core/error.hpp"

namespace rtslam::io {

int default_prefetch_threads(unsigned hardware_threads) {
  return hardware_threads > 1 ? static_cast<int>(std::min(hardware_threads - 1, 4u)) : 0;
}

int default_prefetch_threads() { return default_prefetch_threads(std::thread::hardware_concurrency()); }

// ------------------------------------------------------------------------------------------------ DecodeAhead

DecodeAhead::DecodeAhead(std::vector<std::string> paths, int threads, std::size_t depth)
    : paths_(std::move(paths)), depth_(depth > 0 ? depth : 4 * static_cast<std::size_t>(std::max(threads, 1))) {
  RTSLAM_CHECK(threads > 0, "DecodeAhead needs at least one thread");
  workers_.reserve(static_cast<std::size_t>(threads));
  for (int i = 0; i < threads; ++i) workers_.emplace_back([this] { work(); });
}

DecodeAhead::~DecodeAhead() {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
  }
  work_cv_.notify_all();
  for (auto& w : workers_) w.join();
}

void DecodeAhead::work() {
  std::unique_lock lock(mutex_);
  while (true) {
    // Room: positions [consumer_, consumer_ + depth_) may be decoded (taken or not yet).
    work_cv_.wait(lock, [this] {
      const std::size_t k = std::max(next_, consumer_);
      return stop_ || (k < paths_.size() && k < consumer_ + depth_);
    });
    if (stop_) return;
    const std::size_t k = std::max(next_, consumer_);
    next_ = k + 1;
    lock.unlock();
    Result r;
    try {
      r.image = read_grey_image(paths_[k], &r.why, nullptr, /*keep_16bit=*/true);  // scaled by take()'s caller
    } catch (...) {
      r.error = std::current_exception();
    }
    lock.lock();
    if (k >= consumer_) done_.emplace(k, std::move(r));  // else the consumer has moved past it (seek)
    done_cv_.notify_all();
  }
}

cv::Mat DecodeAhead::take(std::size_t k, std::string* why) {
  RTSLAM_CHECK(k < paths_.size() && k >= consumer_, "DecodeAhead::take out of order");
  std::unique_lock lock(mutex_);
  if (k != consumer_) {
    done_.erase(done_.begin(), done_.lower_bound(k));
    consumer_ = k;
    if (next_ < k) next_ = k;
    work_cv_.notify_all();
  }
  auto it = done_.find(k);
  if (it == done_.end()) {
    const auto t0 = std::chrono::steady_clock::now();
    done_cv_.wait(lock, [&] { return (it = done_.find(k)) != done_.end(); });
    wait_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  Result r = std::move(it->second);
  done_.erase(it);
  consumer_ = k + 1;
  lock.unlock();
  work_cv_.notify_all();  // room for one more
  if (r.error) std::rethrow_exception(r.error);
  if (why) *why = std::move(r.why);
  return r.image;
}

// --------------------------------------------------------------------------------------------- PrefetchSource

PrefetchSource::PrefetchSource(std::unique_ptr<Source> inner, std::size_t depth)
    : inner_(std::move(inner)), depth_(depth > 0 ? depth : 8) {
  if (!inner_) throw ConfigError("prefetching a stream needs a stream");
  image_count_ = inner_->image_count();
  stats_ = std::make_shared<const SourceStats>(inner_->stats());
  reader_ = std::thread([this] { read(); });
}

PrefetchSource::~PrefetchSource() {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
  }
  room_cv_.notify_all();
  inner_->interrupt();  // a live source's wait for its next frame (the reader may be in it) ends now
  reader_.join();
}

void PrefetchSource::read() {
  while (true) {
    Entry e;
    try {
      e.m = inner_->next();
      // The inner stats change with every measurement (its counts): a copy per read, shared by nobody else.
      e.stats = std::make_shared<const SourceStats>(inner_->stats());
    } catch (...) {  // the inner source's error, or no memory for the copy: either ends the stream here
      e.error = std::current_exception();
      try {
        e.stats = std::make_shared<const SourceStats>(inner_->stats());  // with the problem that threw
      } catch (...) {
      }
    }
    const bool last_entry = !e.m || e.error;
    std::unique_lock lock(mutex_);
    room_cv_.wait(lock, [this] { return stop_ || queue_.size() < depth_; });
    if (stop_) return;
    queue_.push_back(std::move(e));
    item_cv_.notify_one();
    if (last_entry) return;
  }
}

std::optional<Measurement> PrefetchSource::next() {
  if (ended_) return std::nullopt;
  std::unique_lock lock(mutex_);
  item_cv_.wait(lock, [this] { return !queue_.empty(); });
  Entry e = std::move(queue_.front());
  queue_.pop_front();
  if (e.stats) stats_ = std::move(e.stats);
  lock.unlock();
  room_cv_.notify_one();
  if (e.error) {
    ended_ = true;
    std::rethrow_exception(e.error);
  }
  if (!e.m) ended_ = true;
  return std::move(e.m);
}

const SourceStats& PrefetchSource::stats() const { return *stats_; }

int start_prefetch(std::unique_ptr<Source>& source, int threads) {
  if (threads < 0) threads = default_prefetch_threads();
  if (threads == 0 || !source) return 0;
  if (source->prefetch(PrefetchOptions{.threads = threads})) return threads;
  source = std::make_unique<PrefetchSource>(std::move(source));
  return 1;
}

}  // namespace rtslam::io
