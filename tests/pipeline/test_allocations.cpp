// The per-frame path allocates nothing after warm-up (DEVELOPERS.md, "Engineering standards"): every heap
// allocation of the process is counted (global operator new replaced in this test binary) while the image SLAM
// pipeline runs on pre-decoded simulated images, and each processed frame's count is set against what it did. A frame
// that creates no landmark (initialization, or reparametrization into a new landmark object with its descriptor)
// must allocate nothing; landmark creation allocates its object, observations and descriptor, which the test
// reports per landmark. Warm-up: the first 2 s, while workspaces grow to their working sizes.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <new>
#include <variant>
#include <vector>

#include "rtslam/io/dataset.hpp"
#include "rtslam/pipeline/image_slam.hpp"

namespace {
std::atomic<long> g_allocations{0};
}  // namespace

void* operator new(std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n > 0 ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n > 0 ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }

namespace rtslam::pipeline {
namespace {

/// The dataset's whole stream, read (images decoded or rendered) before the run, so that the run's own
/// allocations are the pipeline's only.
class PreloadedSource final : public io::Source {
 public:
  explicit PreloadedSource(io::Source& in) : stats_(in.stats()) {
    while (auto m = in.next()) {
      if (std::holds_alternative<io::ImageFrame>(*m)) ++images_;
      stream_.push_back(std::move(*m));
    }
  }
  std::optional<io::Measurement> next() override {
    if (next_ >= stream_.size()) return std::nullopt;
    return std::move(stream_[next_++]);
  }
  const io::SourceStats& stats() const override { return stats_; }
  std::optional<std::size_t> image_count() const override { return images_; }

 private:
  std::vector<io::Measurement> stream_;
  std::size_t next_ = 0, images_ = 0;
  io::SourceStats stats_;
};

void check_allocations(const std::string& config, double duration_s, bool time_offset = false) {
  ImageSlamOptions o = load_image_slam_config(RTSLAM_SOURCE_DIR "/" + config);
  o.sim_duration_s = duration_s;
  o.time_offset.estimate = time_offset;
  io::Dataset ds = make_sim_dataset(o);
  ds.source = std::make_unique<PreloadedSource>(*ds.source);
  // Allocations per processed frame, counted from one frame's end (its observer call) to the next's: a frame's
  // count is its processing with the IMU samples fed before it. (Not per image taken from the source: an image
  // waits for the IMU to cover its time in the robot's clock, and with an estimated camera time offset that time
  // lies beyond its stamp, so it is processed after the next measurements are read.)
  std::vector<long> per_frame;
  per_frame.reserve(*ds.source->image_count() + 1);
  long last = 0;
  bool in_order = true;
  const ImageSlamResult r = run_image_slam(ds, o, {}, [&](const ImageSlamFrame& f) {
    const long now = g_allocations.load(std::memory_order_relaxed);
    in_order = in_order && f.index == static_cast<int>(per_frame.size());
    per_frame.push_back(now - last);
    last = g_allocations.load(std::memory_order_relaxed);
  });
  ASSERT_TRUE(in_order) << "the observer saw the frames out of order";
  ASSERT_EQ(per_frame.size(), r.frames.size());
  const TimeNs warm = r.frames.front().t + from_seconds(2.0);
  int quiet_frames = 0, quiet_allocating = 0, created = 0;
  long quiet_allocations = 0, creating_allocations = 0;
  for (std::size_t k = 1; k < r.frames.size(); ++k) {  // k = 0 also counts the start of the run
    const slam::FrameStats& f = r.frames[k];
    if (f.t < warm) continue;
    const long a = per_frame[k];
    const int new_landmarks = f.initialized + f.reparametrized;
    if (new_landmarks == 0) {
      ++quiet_frames;
      quiet_allocating += a > 0 ? 1 : 0;
      quiet_allocations += a;
      EXPECT_EQ(a, 0) << config << ": frame " << k << " creates no landmark but allocates " << a << " times";
    } else {
      created += new_landmarks;
      creating_allocations += a;
    }
  }
  std::printf("%s: %d frames after warm-up without landmark creation: %d allocate (%ld allocations); %d landmarks "
              "created in the others, %.1f allocations per landmark\n",
              config.c_str(), quiet_frames, quiet_allocating, quiet_allocations, created,
              created > 0 ? static_cast<double>(creating_allocations) / created : 0.0);
  EXPECT_GT(quiet_frames, 10) << "too few frames to check";
}

TEST(Allocations, MonocularFramesAllocateOnlyForNewLandmarks) { check_allocations("config/sim_mono.yaml", 8.0); }

TEST(Allocations, InertialFramesAllocateOnlyForNewLandmarks) { check_allocations("config/sim_mono_imu.yaml", 6.0); }

// With the camera–IMU time offset estimated (camera/time_offset): one more block in every observation, and the
// images processed once the IMU covers their stamp plus the estimate.
TEST(Allocations, InertialFramesWithTimeOffsetAllocateOnlyForNewLandmarks) {
  check_allocations("config/sim_mono_imu.yaml", 6.0, true);
}

}  // namespace
}  // namespace rtslam::pipeline
