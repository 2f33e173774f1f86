#include "rtslam/calib/stream.hpp"

#include <algorithm>
#include <variant>

#include <fmt/format.h>

namespace rtslam::calib {

namespace {

struct IntervalStats {
  std::size_t gaps = 0, backwards = 0, duplicates = 0;
  double median_ms = 0.0, max_ms = 0.0;
};

IntervalStats interval_stats(const std::vector<TimeNs>& t, double gap_factor) {
  IntervalStats s;
  std::vector<TimeNs> d;
  d.reserve(t.size());
  for (std::size_t i = 1; i < t.size(); ++i) {
    const TimeNs dt = t[i] - t[i - 1];
    if (dt < 0) {
      ++s.backwards;
    } else if (dt == 0) {
      ++s.duplicates;
    } else {
      d.push_back(dt);
    }
  }
  if (d.empty()) return s;
  const TimeNs max_d = *std::max_element(d.begin(), d.end());
  const auto mid = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
  std::nth_element(d.begin(), mid, d.end());
  const TimeNs median = *mid;
  s.median_ms = to_seconds(median) * 1e3;
  s.max_ms = to_seconds(max_d) * 1e3;
  for (TimeNs x : d) s.gaps += static_cast<double>(x) > gap_factor * static_cast<double>(median) ? 1 : 0;
  return s;
}

}  // namespace

void StreamReport::with_source_stats(const io::SourceStats& s) {
  backwards_timestamps += s.backwards_timestamps;
  duplicate_timestamps += s.duplicate_timestamps;
  imu_dropouts += s.imu_gaps;
}

std::string StreamReport::line() const {
  return fmt::format(
      "{} image gap(s) (interval max {:.1f} ms, median {:.1f} ms), {} IMU gap(s) (max {:.1f} ms, median {:.2f} ms; "
      "{} dropout(s) reported by the reader), {} out-of-order / {} duplicate timestamp(s)",
      image_gaps, max_image_interval_ms, median_image_interval_ms, imu_gaps, max_imu_interval_ms,
      median_imu_interval_ms, imu_dropouts, backwards_timestamps, duplicate_timestamps);
}

nlohmann::json StreamReport::to_json() const {
  return {{"images", images},
          {"imu_samples", imu_samples},
          {"gap_factor", gap_factor},
          {"image_gaps", image_gaps},
          {"imu_gaps", imu_gaps},
          {"imu_dropouts", imu_dropouts},
          {"backwards_timestamps", backwards_timestamps},
          {"duplicate_timestamps", duplicate_timestamps},
          {"median_image_interval_ms", median_image_interval_ms},
          {"max_image_interval_ms", max_image_interval_ms},
          {"median_imu_interval_ms", median_imu_interval_ms},
          {"max_imu_interval_ms", max_imu_interval_ms}};
}

void StreamTimes::add(const io::Measurement& m) {
  if (const auto* imu = std::get_if<io::ImuSample>(&m)) {
    imu_t_.push_back(imu->t);
  } else if (const auto* f = std::get_if<io::ImageFrame>(&m)) {
    if (f->camera == 0) image_t_.push_back(f->t);  // the first camera: the others share its clock
  }
}

StreamReport StreamTimes::report(double gap_factor) const {
  StreamReport r;
  r.gap_factor = gap_factor;
  r.images = image_t_.size();
  r.imu_samples = imu_t_.size();
  const IntervalStats im = interval_stats(image_t_, gap_factor);
  const IntervalStats iu = interval_stats(imu_t_, gap_factor);
  r.image_gaps = im.gaps;
  r.imu_gaps = iu.gaps;
  r.backwards_timestamps = im.backwards + iu.backwards;
  r.duplicate_timestamps = im.duplicates + iu.duplicates;
  r.median_image_interval_ms = im.median_ms;
  r.max_image_interval_ms = im.max_ms;
  r.median_imu_interval_ms = iu.median_ms;
  r.max_imu_interval_ms = iu.max_ms;
  return r;
}

std::optional<io::Measurement> StreamMonitor::next() {
  auto m = inner_->next();
  if (m) times_.add(*m);
  return m;
}

StreamReport StreamMonitor::report(double gap_factor) const {
  StreamReport r = times_.report(gap_factor);
  r.with_source_stats(inner_->stats());
  return r;
}

}  // namespace rtslam::calib
