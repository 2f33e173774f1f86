// A stream replayed several times (io/repeat.hpp, `rtslam soak --repeat`): every repetition complete, times strictly
// continuing across the seams by one sampling period, counts and problems summed, an empty stream ending.
#include <gtest/gtest.h>

#include <variant>

#include "rtslam/core/error.hpp"
#include "rtslam/io/repeat.hpp"

namespace rtslam::io {
namespace {


// A 200 Hz IMU from t0 for `n` samples with an image every 10th sample (at the same time as that sample).
class TinyStream final : public Source {
 public:
  TinyStream(TimeNs t0, int n, bool with_problem) : t0_(t0), n_(n) {
    if (with_problem) ++stats_.duplicate_timestamps;
  }
  std::optional<Measurement> next() override {
    if (k_ >= n_) return std::nullopt;
    const TimeNs t = t0_ + k_ * 5 * kNsPerMs;
    if (k_ % 10 == 0 && !image_done_) {
      image_done_ = true;
      ImageFrame f;
      f.t = t;
      f.image = cv::Mat(2, 2, CV_8UC1, cv::Scalar(k_ % 256));
      ++stats_.images;
      return f;
    }
    image_done_ = false;
    ++k_;
    ImuSample s;
    s.t = t;
    ++stats_.imu_samples;
    return s;
  }
  const SourceStats& stats() const override { return stats_; }
  std::optional<std::size_t> image_count() const override { return static_cast<std::size_t>((n_ + 9) / 10); }

 private:
  TimeNs t0_;
  int n_, k_ = 0;
  bool image_done_ = false;
  SourceStats stats_;
};

TEST(RepeatSource, ReplaysEveryRepetitionWithContinuingTimes) {
  int opened = 0;
  RepeatSource src([&] { ++opened; return std::make_unique<TinyStream>(1000 * kNsPerMs, 40, opened == 2); }, 3);
  EXPECT_EQ(src.image_count(), std::nullopt);  // unknown before the first repetition is open
  std::vector<TimeNs> imu, images;
  TimeNs last = -1;
  while (auto m = src.next()) {
    const TimeNs t = time_of(*m);
    EXPECT_GE(t, last);
    last = t;
    if (std::holds_alternative<ImuSample>(*m)) imu.push_back(t); else images.push_back(t);
  }
  EXPECT_EQ(opened, 3);
  ASSERT_EQ(imu.size(), 120u);
  ASSERT_EQ(images.size(), 12u);
  for (std::size_t i = 1; i < imu.size(); ++i) EXPECT_EQ(imu[i] - imu[i - 1], 5 * kNsPerMs) << "sample " << i;
  EXPECT_EQ(imu.front(), 1000 * kNsPerMs);
  EXPECT_EQ(images[4], imu[40]);  // the second repetition's first image: with its first IMU sample, 5 ms on
  EXPECT_EQ(src.stats().images, 12u);
  EXPECT_EQ(src.stats().imu_samples, 120u);
  EXPECT_EQ(src.stats().duplicate_timestamps, 1u);  // the second repetition's problem is kept
  EXPECT_EQ(src.image_count(), std::optional<std::size_t>(12));
  EXPECT_FALSE(src.next().has_value());  // stays ended
  EXPECT_EQ(opened, 3);
}

TEST(RepeatSource, OnceIsTheStreamItself) {
  RepeatSource src([] { return std::make_unique<TinyStream>(7 * kNsPerMs, 5, false); }, 1);
  std::vector<TimeNs> t;
  while (auto m = src.next()) t.push_back(time_of(*m));
  ASSERT_EQ(t.size(), 6u);  // one image + five IMU samples
  EXPECT_EQ(t.front(), 7 * kNsPerMs);
  EXPECT_EQ(t.back(), 7 * kNsPerMs + 20 * kNsPerMs);
}

TEST(RepeatSource, EmptyStreamEndsInsteadOfLooping) {
  int opened = 0;
  RepeatSource src([&] { ++opened; return std::make_unique<TinyStream>(0, 0, false); }, 1000);
  EXPECT_FALSE(src.next().has_value());
  EXPECT_EQ(opened, 1);
}

TEST(RepeatSource, RefusesNonsense) {
  EXPECT_THROW(RepeatSource({}, 2), ConfigError);
  EXPECT_THROW(RepeatSource([] { return std::make_unique<TinyStream>(0, 1, false); }, 0), ConfigError);
  RepeatSource broken([] { return std::unique_ptr<Source>(); }, 2);
  EXPECT_THROW(broken.next(), IoError);
}

}  // namespace
}  // namespace rtslam::io
