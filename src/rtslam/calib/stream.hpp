#pragma once
// Timing statistics of a measurement stream: image gaps, IMU gaps and disorder, for the run's report.
//
// A gap is an interval between consecutive timestamps of one stream longer than gap_factor × that stream's median
// interval. Disorder is a timestamp at or before the previous one of its stream (backwards or duplicate) that reached
// the consumer; the readers' own counters (io::SourceStats: backwards, duplicate, IMU dropouts — items they dropped
// under the skip policy or refused under the error policy) are added by `with_source_stats`.
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "rtslam/core/time.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::calib {

struct StreamReport {
  std::size_t images = 0;
  std::size_t imu_samples = 0;
  std::size_t image_gaps = 0;            // image intervals > gap_factor × median
  std::size_t imu_gaps = 0;              // IMU intervals > gap_factor × median
  std::size_t backwards_timestamps = 0;  // seen here plus the source's
  std::size_t duplicate_timestamps = 0;  // seen here plus the source's
  std::size_t imu_dropouts = 0;          // the source's count (io::StreamCheckOptions::max_imu_dropout)
  double median_image_interval_ms = 0.0;
  double median_imu_interval_ms = 0.0;
  double max_image_interval_ms = 0.0;
  double max_imu_interval_ms = 0.0;
  double gap_factor = 1.5;

  /// Adds the reader's counters (items it dropped or refused never reach the consumer).
  void with_source_stats(const io::SourceStats& s);
  std::size_t disorder() const { return backwards_timestamps + duplicate_timestamps; }
  /// "2 image gaps (max 150 ms, median 50 ms), 0 IMU gaps, 0 out-of-order/duplicate timestamps".
  std::string line() const;
  nlohmann::json to_json() const;
};

/// Collects timestamps per stream (camera 0..n and IMU) and computes a StreamReport.
class StreamTimes {
 public:
  void add(const io::Measurement& m);
  void add_image(TimeNs t) { image_t_.push_back(t); }
  void add_imu(TimeNs t) { imu_t_.push_back(t); }
  StreamReport report(double gap_factor = 1.5) const;

 private:
  std::vector<TimeNs> image_t_, imu_t_;
};

/// A pass-through Source that records the timestamps it yields (one int64 per measurement, no other work), for the
/// StreamReport of a whole run. Forwards stats(), image_count() and seek().
class StreamMonitor final : public io::Source {
 public:
  explicit StreamMonitor(std::unique_ptr<io::Source> inner) : inner_(std::move(inner)) {}
  std::optional<io::Measurement> next() override;
  const io::SourceStats& stats() const override { return inner_->stats(); }
  std::optional<std::size_t> image_count() const override { return inner_->image_count(); }
  bool seek(TimeNs t) override { return inner_->seek(t); }
  /// The report of what has been yielded so far, with the inner source's counters.
  StreamReport report(double gap_factor = 1.5) const;

 private:
  std::unique_ptr<io::Source> inner_;
  StreamTimes times_;
};

}  // namespace rtslam::calib
