#include "rtslam/io/live_source.hpp"

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/io/text.hpp"

namespace rtslam::io {

LiveSource::LiveSource(const Options& options)
    : options_(options),
      images_(options.image_capacity),
      imu_(options.imu_capacity),
      reporter_(options.policy, stats_) {
  if (options.image_capacity == 0 || options.imu_capacity == 0) {
    throw ConfigError(fmt::format("live source: queue sizes must be >= 1 (images {}, IMU {})", options.image_capacity,
                                  options.imu_capacity));
  }
  if (!(options.max_image_wait_s >= 0.0 && options.max_image_wait_s <= 3600.0)) {  // (a duration: bounded)
    throw ConfigError(fmt::format("live source: max_image_wait_s = {} must be in [0, 3600]", options.max_image_wait_s));
  }
  if (!(options.end_without_imu_after_s >= 0.0)) {
    throw ConfigError(fmt::format("live source: end_without_imu_after_s = {} must be >= 0",
                                  options.end_without_imu_after_s));
  }
}

void LiveSource::report_locked(std::size_t SourceStats::*counter, const std::string& message, bool file_problem) {
  try {
    reporter_.report(counter, message, file_problem);
  } catch (...) {  // the Error policy: the stream ends here
    if (!error_) error_ = std::current_exception();
    closed_ = true;
  }
}

void LiveSource::push_image(ImageFrame frame) {
  {
    std::lock_guard lock(mutex_);
    if (closed_) return;
    if (last_image_t_ && frame.t <= *last_image_t_) {
      const bool same = frame.t == *last_image_t_;
      report_locked(same ? &SourceStats::duplicate_timestamps : &SourceStats::backwards_timestamps,
                    fmt::format("{}: image stamp {} s {} (previous {} s)", frame.path, format_seconds(frame.t),
                                same ? "repeats" : "goes backwards", format_seconds(*last_image_t_)),
                    false);
    } else {
      last_image_t_ = frame.t;
      if (!first_image_t_) first_image_t_ = frame.t;
      if (images_.size() >= options_.image_capacity) {
        images_.pop_front();
        if (++stats_.live_dropped_images <= 10 || stats_.live_dropped_images % 100 == 0) {
          logger(options_.log_name)->warn("the filter falls behind: {} image(s) dropped so far (queue of {})",
                                          stats_.live_dropped_images, options_.image_capacity);
        }
      }
      images_.push_back({std::move(frame), Clock::now()});
    }
  }
  changed_.notify_all();
}

void LiveSource::push_imu(const ImuSample& sample) {
  {
    std::lock_guard lock(mutex_);
    if (closed_) return;
    const auto at = [&] { return fmt::format("IMU sample at t = {} s", format_seconds(sample.t)); };
    if (!sample.gyro.allFinite() || !sample.accel.allFinite()) {
      report_locked(&SourceStats::non_finite, fmt::format("{}: non-finite value", at()), false);
    } else if (last_imu_t_ && sample.t <= *last_imu_t_) {
      const bool same = sample.t == *last_imu_t_;
      report_locked(same ? &SourceStats::duplicate_timestamps : &SourceStats::backwards_timestamps,
                    fmt::format("{}: stamp {} (previous {} s)", at(), same ? "repeats" : "goes backwards",
                                format_seconds(*last_imu_t_)),
                    false);
    } else {
      last_imu_t_ = sample.t;
      if (imu_.size() >= options_.imu_capacity) {
        imu_.pop_front();
        if (++stats_.live_dropped_imu_samples <= 10 || stats_.live_dropped_imu_samples % 1000 == 0) {
          logger(options_.log_name)->warn("the filter falls behind: {} IMU sample(s) dropped so far (queue of {})",
                                          stats_.live_dropped_imu_samples, options_.imu_capacity);
        }
      }
      imu_.push_back(sample);
    }
  }
  changed_.notify_all();
}

void LiveSource::report_bad_image(const std::string& message) {
  report_problem(&SourceStats::undecodable_images, message, true);
}

void LiveSource::report_problem(std::size_t SourceStats::*counter, const std::string& message, bool file_problem) {
  {
    std::lock_guard lock(mutex_);
    if (closed_) return;
    report_locked(counter, message, file_problem);
  }
  changed_.notify_all();
}

void LiveSource::fail(std::exception_ptr error) {
  {
    std::lock_guard lock(mutex_);
    if (!error_ && !closed_) error_ = std::move(error);
    closed_ = true;
  }
  changed_.notify_all();
}

void LiveSource::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  changed_.notify_all();
}

std::optional<Measurement> LiveSource::next() {
  std::unique_lock lock(mutex_);
  while (true) {
    if (!imu_.empty() && (images_.empty() || imu_.front().t <= images_.front().frame.t)) {
      ImuSample s = imu_.front();
      imu_.pop_front();
      ++stats_.imu_samples;
      return s;
    }
    if (!images_.empty()) {
      const QueuedImage& q = images_.front();
      const auto deadline = q.arrived + std::chrono::duration_cast<Clock::duration>(
                                            std::chrono::duration<double>(options_.max_image_wait_s));
      const bool covered = !options_.with_imu || (last_imu_t_ && *last_imu_t_ >= q.frame.t);
      // One reading of the clock for both decisions: read twice, the deadline could pass between them and release
      // a frame that no IMU sample will ever cover instead of dropping it.
      const bool waited_enough = closed_ || Clock::now() >= deadline;
      if (!covered && !last_imu_t_ && waited_enough) {
        // No IMU sample yet after the wait (or ever: the source closed): an inertial filter starts from the IMU, so
        // the frame is of no use (released, it would be parked until the IMU came, and an IMU stream started late
        // would fill the pipeline).
        const TimeNs t = q.frame.t;
        images_.pop_front();
        const std::size_t n = ++stats_.live_images_before_imu;
        if (n == 1 || n % 100 == 0) {
          logger(options_.log_name)
              ->warn("no IMU sample yet: {} camera frame(s) dropped waiting for the IMU's first one", n);
        }
        // (An image was queued, so first_image_t_ is set; the span in double: no integer overflow.)
        const double span_s = 1e-9 * (static_cast<double>(t) - static_cast<double>(*first_image_t_));
        if (!closed_ && options_.end_without_imu_after_s > 0.0 && span_s >= options_.end_without_imu_after_s) {
          logger(options_.log_name)
              ->warn("no IMU sample in the {:g} s of input to process ({} camera frame(s) dropped): the live input "
                     "ends",
                     options_.end_without_imu_after_s, n);
          closed_ = true;  // the frames still queued are dropped and counted as well
        }
        continue;
      }
      if (covered || waited_enough) {
        ImageFrame frame = q.frame;
        images_.pop_front();
        ++stats_.images;
        return frame;
      }
      changed_.wait_until(lock, deadline);
      continue;
    }
    if (closed_) {
      if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
      return std::nullopt;
    }
    changed_.wait(lock);
  }
}

const SourceStats& LiveSource::stats() const {
  std::lock_guard lock(mutex_);
  consumer_stats_ = stats_;
  return consumer_stats_;
}

std::size_t LiveSource::dropped_images() const {
  std::lock_guard lock(mutex_);
  return stats_.live_dropped_images;
}

std::size_t LiveSource::dropped_imu_samples() const {
  std::lock_guard lock(mutex_);
  return stats_.live_dropped_imu_samples;
}

}  // namespace rtslam::io
