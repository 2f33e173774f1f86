#pragma once
// A measurement Source fed by other threads (the ROS callbacks of rtslam_ros; the camera and IMU-stream threads of
// LiveRigSource, live_rig.hpp) and read by the pipeline's thread: two bounded queues, images and IMU samples, merged
// by time.
//
// Order: next() yields the oldest queued measurement, IMU first at equal times. When IMU samples are expected, an
// image waits in the queue until an IMU sample at or after its time has arrived (so that the IMU samples before it
// are yielded first), or for at most `max_image_wait_s` of wall time (the IMU stream lags or stopped; the pipeline
// then waits for IMU data itself), or until the source is closed. An image still waiting (or left at the close) when
// no IMU sample has come at all is dropped (counted: SourceStats::live_images_before_imu; an inertial filter starts
// from the IMU, and an IMU stream started late would otherwise fill the pipeline with frames it can only park; with
// `end_without_imu_after_s` the stream ends once the dropped frames span that time). The stream is time-ordered per
// sensor, not across them: an image that arrives after IMU samples later than it were yielded (a camera frame
// reaches the host tens of ms after its exposure, an IMU sample within a millisecond) comes after those samples; the
// inertial robot buffers IMU samples ahead of its time (slam/robot.hpp), so the image is still processed at its own
// time.
//
// Checks: per stream, stamps must increase strictly (duplicates and backwards stamps), IMU values must be finite,
// images the producer could not convert are counted as undecodable (report_bad_image), and producers report their own
// problems (report_problem). Under the Skip policy (the default: the ROS node's live stream is never stopped by one
// bad message) the offending item is dropped and counted; under Error the first problem ends the stream: next()
// yields what was queued before it, then throws it (fail() does the same with a producer's own error). When a queue
// is full its oldest element is dropped: the filter is slower than the sensors and keeping up matters more than old
// data (counted in SourceStats::live_dropped_images / live_dropped_imu_samples, logged).
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <exception>
#include <mutex>
#include <optional>
#include <string>

#include "rtslam/core/ring_buffer.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::io {

class LiveSource final : public Source {
 public:
  struct Options {
    std::size_t image_capacity = 30;  // queued images (≥ 1)
    std::size_t imu_capacity = 4000;  // queued IMU samples (≥ 1): 20 s at 200 Hz
    bool with_imu = false;            // images wait for the IMU samples that cover them
    double max_image_wait_s = 0.5;    // wall time an image waits for IMU coverage at most
    // > 0: while no IMU sample has come, the stream ends at the first image dropped this long (s) after the first
    // image pushed: a run limited in time (--start-at + --stop-after) ends even if its IMU never delivers.
    double end_without_imu_after_s = 0.0;
    BadInputPolicy policy = BadInputPolicy::Skip;  // Error: the first problem ends the stream (see above)
    std::string log_name = "live";                 // the logger of its warnings ("ros" for the node)
  };
  explicit LiveSource(const Options& options);

  // Producers (any thread).
  void push_image(ImageFrame frame);
  void push_imu(const ImuSample& sample);
  /// An image the producer could not convert (unsupported encoding, bad buffer): counted and logged.
  void report_bad_image(const std::string& message);
  /// A producer's problem under `counter` (a malformed line of an IMU stream...), handled by the policy.
  void report_problem(std::size_t SourceStats::*counter, const std::string& message, bool file_problem = false);
  /// Whether the first reported problem ends the stream (the Error policy).
  bool problems_end_the_stream() const { return options_.policy == BadInputPolicy::Error; }
  /// A producer failed (its input is broken or gone): the stream ends, next() yields what was queued before and
  /// then rethrows `error`. The first failure wins; later pushes are ignored.
  void fail(std::exception_ptr error);
  /// No more input: next() yields what is queued, then nullopt.
  void close();

  // Consumer (one thread).
  /// Blocks until a measurement is ready (see the header comment) or the source is closed and empty.
  std::optional<Measurement> next() override;
  /// Counters as of the call (a copy made under the source's lock: producers may be running).
  const SourceStats& stats() const override;
  /// Ends a next() that waits for input: it returns what is queued, then the end (as close()).
  void interrupt() override { close(); }

  std::size_t dropped_images() const;
  std::size_t dropped_imu_samples() const;

 private:
  using Clock = std::chrono::steady_clock;
  struct QueuedImage {
    ImageFrame frame;
    Clock::time_point arrived;
  };

  Options options_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  RingBuffer<QueuedImage> images_;
  RingBuffer<ImuSample> imu_;
  SourceStats stats_;
  mutable SourceStats consumer_stats_;  // stats()'s copy
  BadInputReporter reporter_;
  std::exception_ptr error_;  // thrown by next() once the queues before it are drained
  std::optional<TimeNs> last_image_t_;  // newest accepted stamps
  std::optional<TimeNs> last_imu_t_;
  std::optional<TimeNs> first_image_t_;  // the first accepted image's stamp (end_without_imu_after_s counts from it)
  bool closed_ = false;

  /// Counts a problem (the lock held); under Error the reporter's exception ends the stream (error_, closed_).
  void report_locked(std::size_t SourceStats::*counter, const std::string& message, bool file_problem);
};

}  // namespace rtslam::io
