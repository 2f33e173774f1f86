#pragma once
// Real-time replay (`rtslam run --realtime [SPEED]`): another stream's measurements are released at its sensor clock
// (× speed) by an acquisition thread, as a live sensor would deliver them, and the consumer (the filter) takes them as
// it can. IMU samples are never dropped; of the images of a camera that arrived while the filter was busy only the
// newest is kept — the older ones are dropped and counted (the paper's "the filter processes the most recent data").
// The acquisition thread also reads and decodes ahead, so decoding overlaps the filter on a second core.
//
// The replay's clock starts when the consumer first asks for a measurement (the first one is read and decoded ahead
// meanwhile): the time the caller spends setting up after constructing the source (the filter, outputs, viewer) is
// not counted against the stream, and no image is dropped for it. A live source (`live`: a camera, whose frames
// arrive at its own clock) is not paced again: its measurements are released as they arrive, from construction on —
// frames the camera delivers while the filter is still setting up are superseded and counted as dropped, as they
// would be on a robot.
//
// Stopping early (an interrupted run): stop() ends the acquisition thread and brings the statistics up to
// date: the inner source's as far as it was read, and the images released but never taken (images_left). A consumer
// waiting in next() for a measurement that may be long in coming (a replay's timestamp gap, a live camera delivering
// nothing usable) returns the end of the stream as soon as the flag given to set_interrupt() is raised, having
// stopped (stop(): the statistics are then final).
//
// Lag: when the consumer takes an image, how long after its release time it is (the filter's delay behind the
// clock); a run that keeps up has a lag of about one frame's processing time, one that falls behind drops images
// instead of letting the lag grow. Both figures are in RealtimeStats.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "rtslam/io/source.hpp"

namespace rtslam::io {

struct RealtimeStats {
  std::size_t images_released = 0;  // by the acquisition thread
  std::size_t images_taken = 0;     // by the consumer
  std::size_t images_dropped = 0;   // superseded by a newer image of the same camera before being taken (counted
                                    // when the newer one is released)
  std::size_t images_left = 0;     // released but neither taken nor dropped when the run stopped (stop())
  std::size_t imu_samples = 0;
  double max_lag_s = 0.0;           // of the images taken (wall time after their release time)
  double mean_lag_s = 0.0;
  double reader_late_s = 0.0;       // worst delay of the acquisition itself (reading/decoding slower than the clock)
};

class RealtimeSource final : public Source {
 public:
  static constexpr std::size_t kDefaultMaxQueue = 8192;
  static constexpr double kMinSpeed = 1e-3, kMaxSpeed = 1000.0;
  /// speed: sensor seconds per wall second (1: real time), in [kMinSpeed, kMaxSpeed]; max_queue bounds what waits
  /// (IMU samples and images); live: the inner source delivers at its own clock (a camera; speed must be 1), released
  /// as it arrives.
  RealtimeSource(std::unique_ptr<Source> inner, double speed, std::size_t max_queue = kDefaultMaxQueue,
                 bool live = false);
  ~RealtimeSource() override;
  RealtimeSource(const RealtimeSource&) = delete;
  RealtimeSource& operator=(const RealtimeSource&) = delete;

  /// The next measurement in time order, waiting for its release; images superseded while waiting are skipped.
  /// Rethrows, at its place in the stream, an error the inner source threw.
  std::optional<Measurement> next() override;
  /// The inner source's statistics as of the stream's start, and complete once next() has returned its end or
  /// stop() has been called. Call from the consumer's thread.
  const SourceStats& stats() const override;
  std::optional<std::size_t> image_count() const override { return count_; }
  RealtimeStats realtime() const;
  /// Ends the acquisition (joins its thread; idempotent): next() returns the end from now on, stats() is complete
  /// for what was read and realtime() counts the images left untaken. The destructor stops as well.
  void stop();
  /// next() stops (stop()) and returns the end of the stream while it waits, once *flag is true (checked every
  /// 50 ms). Null: never.
  void set_interrupt(const std::atomic<bool>* flag) { interrupt_ = flag; }

 private:
  void acquire();

  std::unique_ptr<Source> inner_;
  double speed_;
  std::size_t max_queue_;
  std::optional<std::size_t> count_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  struct Item {
    Measurement m;
    std::chrono::steady_clock::time_point released;
    bool superseded;  // an image with a newer one of its camera behind it: dropped (pixels freed), skipped by next()
  };
  std::deque<Item> queue_;
  std::vector<Item*> newest_image_;  // per camera index: its newest image in the queue (null: none)
  bool live_ = false;
  bool consumer_started_ = false;  // next() was called: a replay's clock runs
  bool ended_ = false;
  bool stop_ = false;
  bool stopped_ = false;  // stop() has joined the thread
  const std::atomic<bool>* interrupt_ = nullptr;
  std::exception_ptr error_;
  RealtimeStats stats_;
  double lag_sum_s_ = 0.0;
  SourceStats inner_stats_;              // written by the acquisition thread at its end, and by stop()
  mutable SourceStats consumer_stats_;   // stats()'s copy of it, made under the lock
  std::thread thread_;
};

}  // namespace rtslam::io
