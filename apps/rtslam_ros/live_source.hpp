#pragma once
// A measurement Source fed by other threads (the ROS callbacks of rtslam_ros) and read by the pipeline's thread:
// two bounded queues, images and IMU samples, merged by time.
//
// Order: next() yields the oldest queued measurement, IMU first at equal times. When IMU samples are expected, an
// image waits in the queue until an IMU sample at or after its time has arrived (so that the IMU samples before it
// are yielded first), or for at most `max_image_wait_s` of wall time (the IMU stream lags or stopped; the
// pipeline then waits for IMU data itself), or until the source is closed.
//
// Checks (the Skip policy of source.hpp: a live stream is never stopped by one bad message): per stream, stamps
// must increase strictly (duplicates and backwards stamps are dropped and counted), IMU values must be finite,
// images the producer could not convert are counted as undecodable (report_bad_image). When a queue is full its
// oldest element is dropped: the filter is slower than the sensors and keeping up matters more than old data
// (counted: dropped_images(), dropped_imu_samples(), logged).
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <mutex>
#include <optional>
#include <string>

#include "rtslam/core/ring_buffer.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::ros_node {

class LiveSource final : public io::Source {
 public:
  struct Options {
    std::size_t image_capacity = 30;  // queued images (≥ 1)
    std::size_t imu_capacity = 4000;  // queued IMU samples (≥ 1): 20 s at 200 Hz
    bool with_imu = false;            // images wait for the IMU samples that cover them
    double max_image_wait_s = 0.5;    // wall time an image waits for IMU coverage at most
  };
  explicit LiveSource(const Options& options);

  // Producers (any thread).
  void push_image(io::ImageFrame frame);
  void push_imu(const io::ImuSample& sample);
  /// An image the producer could not convert (unsupported encoding, bad buffer): counted and logged.
  void report_bad_image(const std::string& message);
  /// No more input: next() yields what is queued, then nullopt.
  void close();

  // Consumer (one thread).
  /// Blocks until a measurement is ready (see the header comment) or the source is closed and empty.
  std::optional<io::Measurement> next() override;
  /// Counters; read them once the stream has ended (the producers update them under the source's lock).
  const io::SourceStats& stats() const override { return stats_; }

  std::size_t dropped_images() const;
  std::size_t dropped_imu_samples() const;

 private:
  using Clock = std::chrono::steady_clock;
  struct QueuedImage {
    io::ImageFrame frame;
    Clock::time_point arrived;
  };

  Options options_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  RingBuffer<QueuedImage> images_;
  RingBuffer<io::ImuSample> imu_;
  io::SourceStats stats_;
  io::BadInputReporter reporter_;
  std::optional<TimeNs> last_image_t_;  // newest accepted stamps
  std::optional<TimeNs> last_imu_t_;
  std::size_t dropped_images_ = 0;
  std::size_t dropped_imu_ = 0;
  bool closed_ = false;
};

}  // namespace rtslam::ros_node
