#pragma once
// A stream replayed several times in a row, as one longer stream: for soak runs (hours of data from a recording of
// minutes). Each repetition is the inner stream opened anew (open()), its times shifted so that it starts one
// sampling period (the smallest interval met between two measurements of the first repetition) after the previous
// repetition's last measurement. The sensor seems to jump back to where the recording started: the filter sees a
// discontinuity at each seam (the health monitor's business), never a time going backwards.
#include <functional>
#include <memory>

#include "rtslam/io/source.hpp"

namespace rtslam::io {

class RepeatSource final : public Source {
 public:
  /// `open` returns the inner stream from its start (called once per repetition); `times` >= 1.
  RepeatSource(std::function<std::unique_ptr<Source>()> open, int times);
  std::optional<Measurement> next() override;
  /// The counts of the finished repetitions plus the current one's.
  const SourceStats& stats() const override;
  std::optional<std::size_t> image_count() const override;
  /// Remembered and applied to every repetition's stream.
  bool prefetch(const PrefetchOptions& options) override;
  int repetition() const { return repetition_; }  // 0-based index of the repetition being read

 private:
  void open_next();
  std::function<std::unique_ptr<Source>()> open_;
  int times_;
  int repetition_ = 0;
  std::unique_ptr<Source> inner_;
  std::optional<PrefetchOptions> prefetch_;
  SourceStats finished_;           // repetitions read to their end
  mutable SourceStats view_;       // finished_ + the current one's (stats())
  TimeNs shift_ = 0;               // added to the current repetition's times
  std::optional<TimeNs> first_t_;  // the current repetition's first (unshifted) time
  std::optional<TimeNs> last_out_t_;  // the last (shifted) time handed out
  std::optional<TimeNs> last_odometry_t_;  // the last (shifted) odometry reading's end handed out
  std::optional<TimeNs> prev_t_;      // the previous unshifted time of the first repetition
  TimeNs period_ = 0;                 // the smallest positive interval of the first repetition
  std::optional<std::size_t> images_per_repetition_;
  bool done_ = false;
};

}  // namespace rtslam::io
