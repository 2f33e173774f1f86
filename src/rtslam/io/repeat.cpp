#include "rtslam/io/repeat.hpp"

#include <algorithm>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/io/prefetch.hpp"

namespace rtslam::io {

RepeatSource::RepeatSource(std::function<std::unique_ptr<Source>()> open, int times)
    : open_(std::move(open)), times_(times) {
  if (!open_) throw ConfigError("a repeated stream needs a way to open its stream");
  if (times < 1 || times > 100000) {
    throw ConfigError(fmt::format("repeat: {} repetitions, must be in [1, 100000]", times));
  }
}

void RepeatSource::open_next() {
  inner_ = open_();
  if (!inner_) throw IoError(fmt::format("repeat: repetition {} could not be opened", repetition_ + 1));
  if (prefetch_) start_prefetch(inner_, prefetch_->threads);
  first_t_.reset();
}

bool RepeatSource::prefetch(const PrefetchOptions& options) {
  prefetch_ = options;
  if (inner_) start_prefetch(inner_, options.threads);
  return true;
}

std::optional<Measurement> RepeatSource::next() {
  if (done_) return std::nullopt;
  if (!inner_) open_next();
  for (;;) {
    auto m = inner_->next();
    if (m) {
      const TimeNs t = time_of(*m);
      if (!first_t_) {
        first_t_ = t;
        // The first measurement of a later repetition comes one period after the previous one's last.
        if (last_out_t_) shift_ = *last_out_t_ + std::max<TimeNs>(period_, 1) - t;
      }
      if (repetition_ == 0) {
        if (prev_t_ && t > *prev_t_ && (period_ == 0 || t - *prev_t_ < period_)) period_ = t - *prev_t_;
        prev_t_ = t;
      }
      const TimeNs shifted = t + shift_;
      std::visit([shifted](auto& x) { x.t = shifted; }, *m);
      if (auto* o = std::get_if<OdometrySample>(&*m)) {
        // An increment's start moves with it; at a repetition's seam it starts where the previous reading ended
        // (increments never overlap).
        o->t_from += shifted - t;
        if (last_odometry_t_) o->t_from = std::max(o->t_from, *last_odometry_t_);
        last_odometry_t_ = shifted;
      }
      last_out_t_ = shifted;
      return m;
    }
    finished_.images += inner_->stats().images;
    finished_.imu_samples += inner_->stats().imu_samples;
    finished_.add_problems(inner_->stats());
    if (const auto n = inner_->image_count()) images_per_repetition_ = *n;
    inner_.reset();
    if (repetition_ + 1 >= times_ || !first_t_) {  // done, or an empty stream (repeating it would loop for ever)
      done_ = true;
      return std::nullopt;
    }
    ++repetition_;
    open_next();
  }
}

const SourceStats& RepeatSource::stats() const {
  view_ = finished_;
  if (inner_) {
    view_.images += inner_->stats().images;
    view_.imu_samples += inner_->stats().imu_samples;
    view_.add_problems(inner_->stats());
  }
  return view_;
}

std::optional<std::size_t> RepeatSource::image_count() const {
  const auto n = inner_ ? inner_->image_count() : images_per_repetition_;
  if (!n) return std::nullopt;
  return *n * static_cast<std::size_t>(times_);
}

}  // namespace rtslam::io
