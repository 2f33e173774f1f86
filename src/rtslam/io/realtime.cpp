#include "rtslam/io/realtime.hpp"

#include <algorithm>
#include <chrono>
#include <variant>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"

namespace rtslam::io {

using Clock = std::chrono::steady_clock;
constexpr double kMaxWaitS = 365.0 * 86400.0;

RealtimeSource::RealtimeSource(std::unique_ptr<Source> inner, double speed, std::size_t max_queue, bool live)
    : inner_(std::move(inner)), speed_(speed), max_queue_(max_queue), live_(live) {
  RTSLAM_CHECK(inner_ != nullptr, "RealtimeSource: null source");
  if (!(speed >= kMinSpeed && speed <= kMaxSpeed)) {
    throw ConfigError(fmt::format("realtime speed = {} must be in [{}, {}] (sensor seconds per wall second)", speed,
                                  kMinSpeed, kMaxSpeed));
  }
  if (max_queue_ < 16) throw ConfigError("RealtimeSource: max_queue must be >= 16");
  if (live_ && speed_ != 1.0)
    throw ConfigError(fmt::format("realtime speed = {}: a live source runs at speed 1", speed));
  count_ = inner_->image_count();
  inner_stats_ = inner_->stats();
  thread_ = std::thread([this] { acquire(); });
}

RealtimeSource::~RealtimeSource() { stop(); }

void RealtimeSource::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopped_) return;
    stop_ = true;
  }
  changed_.notify_all();
  if (inner_) inner_->interrupt();  // a live source waiting for its next frame (a gap in a stand-in file) returns now
  if (thread_.joinable()) thread_.join();
  std::lock_guard<std::mutex> lock(mutex_);
  stopped_ = true;
  ended_ = true;
  if (inner_) inner_stats_ = inner_->stats();  // the thread is gone: the inner source is ours, its counts final
  for (const Item& item : queue_) {
    if (!item.superseded && std::holds_alternative<ImageFrame>(item.m)) ++stats_.images_left;
  }
  queue_.clear();
  newest_image_.clear();
  error_ = nullptr;  // an error met after the consumer stopped reading belongs to no measurement it took
  inner_.reset();    // a live camera is released now (nothing reads the inner source after the join)
}

void RealtimeSource::acquire() {
  std::optional<TimeNs> t0;
  Clock::time_point wall0;
  try {
    while (true) {
      std::optional<Measurement> m = inner_->next();
      if (!m) break;
      const TimeNs t = time_of(*m);
      std::unique_lock<std::mutex> lock(mutex_);
      if (!t0 && !live_) {  // a replay's clock starts when the consumer is ready (the first measurement is read)
        changed_.wait(lock, [&] { return stop_ || consumer_started_; });
        if (stop_) return;
        t0 = t;
        wall0 = Clock::now();
      }
      // The release time; the sensor time since the first measurement clamped so that the cast cannot overflow
      // (a timestamp far from the first: a year of wall time is as good as never).
      const auto due = live_ ? Clock::now()
                             : wall0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(
                                           std::clamp(to_seconds(t - *t0) / speed_, -kMaxWaitS, kMaxWaitS)));
      // Wait for the release time (or a stop); a full queue (the consumer far behind on IMU samples) waits too.
      changed_.wait_until(lock, due, [&] { return stop_; });
      changed_.wait(lock, [&] { return stop_ || queue_.size() < max_queue_; });
      if (stop_) return;
      const auto now = Clock::now();
      stats_.reader_late_s = std::max(stats_.reader_late_s, std::chrono::duration<double>(now - due).count());
      const auto* img = std::get_if<ImageFrame>(&*m);
      const auto c = img != nullptr ? static_cast<std::size_t>(std::max(img->camera, 0)) : 0;
      if (img != nullptr) {
        // The camera's image still waiting is superseded: dropped now, its pixels freed (a stalled filter holds
        // at most one image per camera, whatever the queue's length in IMU samples).
        if (newest_image_.size() <= c) newest_image_.resize(c + 1, nullptr);
        if (Item* older = newest_image_[c]; older != nullptr) {
          older->superseded = true;
          std::get<ImageFrame>(older->m).image.release();
          ++stats_.images_dropped;
        }
        ++stats_.images_released;
      } else {
        ++stats_.imu_samples;
      }
      queue_.push_back(Item{std::move(*m), due, false});
      if (img != nullptr) newest_image_[c] = &queue_.back();  // deque: push_back/pop_front keep it valid
      lock.unlock();
      changed_.notify_all();
    }
  } catch (...) {
    std::lock_guard<std::mutex> lock(mutex_);
    error_ = std::current_exception();
  }
  std::lock_guard<std::mutex> lock(mutex_);
  ended_ = true;
  try {
    inner_stats_ = inner_->stats();
  } catch (...) {  // out of memory copying the messages: the counts stay as last copied, the stream still ends
    if (!error_) error_ = std::current_exception();
  }
  changed_.notify_all();
}

std::optional<Measurement> RealtimeSource::next() {
  std::unique_lock<std::mutex> lock(mutex_);
  if (!consumer_started_) {
    consumer_started_ = true;
    changed_.notify_all();
  }
  while (true) {
    const auto ready = [&] { return !queue_.empty() || ended_; };
    if (interrupt_ == nullptr) {
      changed_.wait(lock, ready);
    } else {
      while (!changed_.wait_for(lock, std::chrono::milliseconds(50), ready)) {
        if (interrupt_->load()) {
          // Stopped now: the statistics are those of the stream as far as it was read (a live source that dropped
          // every frame waiting for its IMU says so), not the ones copied at the start.
          lock.unlock();
          stop();
          return std::nullopt;
        }
      }
    }
    if (queue_.empty()) {
      if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
      return std::nullopt;
    }
    if (const auto* img = std::get_if<ImageFrame>(&queue_.front().m); img != nullptr && !queue_.front().superseded) {
      newest_image_[static_cast<std::size_t>(std::max(img->camera, 0))] = nullptr;  // it is the camera's newest
    }
    Item item = std::move(queue_.front());
    queue_.pop_front();
    changed_.notify_all();  // room in the queue
    if (item.superseded) continue;  // a newer image of this camera arrived before this one was taken (counted)
    if (!std::holds_alternative<ImageFrame>(item.m)) return std::move(item.m);
    const double lag = std::chrono::duration<double>(Clock::now() - item.released).count();
    ++stats_.images_taken;
    lag_sum_s_ += lag;
    stats_.max_lag_s = std::max(stats_.max_lag_s, lag);
    stats_.mean_lag_s = lag_sum_s_ / static_cast<double>(stats_.images_taken);
    return std::move(item.m);
  }
}

const SourceStats& RealtimeSource::stats() const {
  std::lock_guard<std::mutex> lock(mutex_);
  consumer_stats_ = inner_stats_;  // a copy: the acquisition thread may write inner_stats_ once the lock is released
  return consumer_stats_;
}

RealtimeStats RealtimeSource::realtime() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return stats_;
}

}  // namespace rtslam::io
