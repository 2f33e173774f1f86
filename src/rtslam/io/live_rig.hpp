#pragma once
// A live camera paired with a live IMU stream (`rtslam run --dataset camera:N --imu-stream PATH`, docs/datasets.md
// "Live camera with an IMU"): two acquisition threads, one reading the camera (a CameraSource: a V4L2 device or a
// video standing in for one) and one reading the IMU stream (ImuStreamReader), feed a LiveSource that merges them by
// time, each image held until the IMU has covered it (at most LiveSource::Options::max_image_wait_s). The camera's
// frames and the IMU's samples must be stamped on one clock: the steady clock (imu_stream.hpp says how the IMU's are).
//
// The stream ends when the IMU stream ends (its writer closed it; logged), when the camera fails (its error is thrown
// by next() after the measurements queued before it), on interrupt(), or, with LiveSource::Options::
// end_without_imu_after_s (--stop-after), when the frames dropped while no IMU sample has come span that time. A run
// reads it through RealtimeSource (live), which takes the newest image and never drops an IMU sample.
#include <atomic>
#include <memory>
#include <mutex>
#include <thread>

#include "rtslam/io/imu_stream.hpp"
#include "rtslam/io/live_source.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::io {

class LiveRigSource final : public Source {
 public:
  /// Starts both threads. `options.with_imu` is set (images wait for their IMU).
  LiveRigSource(std::unique_ptr<Source> camera, std::unique_ptr<ImuStreamReader> imu, LiveSource::Options options);
  ~LiveRigSource() override;
  LiveRigSource(const LiveRigSource&) = delete;
  LiveRigSource& operator=(const LiveRigSource&) = delete;

  std::optional<Measurement> next() override;
  /// What was yielded (images, IMU samples) and every problem met: the merge's, the IMU stream's and the camera's.
  /// Thread-safe.
  const SourceStats& stats() const override;
  /// Stops both threads' reading (the camera's wait for a stand-in frame, the IMU's wait for a line) and ends the
  /// stream: next() returns what is queued, then the end. Thread-safe.
  void interrupt() override;

 private:
  std::unique_ptr<Source> camera_;
  std::unique_ptr<ImuStreamReader> imu_;
  LiveSource live_;
  std::atomic<bool> stop_{false};  // interrupt(): the camera thread's loop ends
  mutable std::mutex mutex_;
  SourceStats camera_stats_;          // the camera's, copied by its thread after each frame
  mutable SourceStats merged_;        // stats()'s copy (under mutex_)
  std::thread camera_thread_, imu_thread_;
};

}  // namespace rtslam::io
