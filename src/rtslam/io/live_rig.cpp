#include "rtslam/io/live_rig.hpp"

#include <exception>
#include <variant>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"

namespace rtslam::io {

namespace {

LiveSource::Options with_imu(LiveSource::Options o) {
  o.with_imu = true;
  return o;
}

}  // namespace

LiveRigSource::LiveRigSource(std::unique_ptr<Source> camera, std::unique_ptr<ImuStreamReader> imu,
                             LiveSource::Options options)
    : camera_(std::move(camera)), imu_(std::move(imu)), live_(with_imu(options)) {
  RTSLAM_CHECK(camera_ != nullptr && imu_ != nullptr, "LiveRigSource: null camera or IMU stream");
  camera_stats_ = camera_->stats();
  imu_thread_ = std::thread([this] {
    try {
      if (imu_->run(live_)) {
        logger("live")->warn("{}: the IMU stream ended (its writer closed it) after {} lines: the live input ends",
                             imu_->path(), imu_->lines());
        live_.close();
      }
    } catch (...) {
      live_.fail(std::current_exception());
    }
  });
  const auto read_camera = [this] {
    const auto keep_stats = [this] {
      std::lock_guard lock(mutex_);
      camera_stats_ = camera_->stats();
    };
    try {
      // A device's next() is not interrupted (it returns its next frame, at most a period later): the flag ends the
      // loop.
      while (!stop_) {
        auto m = camera_->next();
        keep_stats();
        if (!m) break;
        if (auto* img = std::get_if<ImageFrame>(&*m); img != nullptr) live_.push_image(std::move(*img));
      }
    } catch (...) {
      keep_stats();
      live_.fail(std::current_exception());
      return;
    }
    live_.close();  // the camera ended (interrupted)
  };
  try {
    camera_thread_ = std::thread(read_camera);
  } catch (...) {  // no thread: the IMU's is stopped before the error leaves the constructor
    interrupt();
    imu_thread_.join();
    throw;
  }
}

LiveRigSource::~LiveRigSource() {
  interrupt();
  if (camera_thread_.joinable()) camera_thread_.join();
  if (imu_thread_.joinable()) imu_thread_.join();
}

void LiveRigSource::interrupt() {
  stop_ = true;
  imu_->interrupt();
  camera_->interrupt();
  live_.close();
}

std::optional<Measurement> LiveRigSource::next() { return live_.next(); }

const SourceStats& LiveRigSource::stats() const {
  std::lock_guard lock(mutex_);
  merged_ = live_.stats();  // (its own lock inside: the camera thread takes mutex_ alone, never the other way)
  // The camera's images are those the merge yielded (it may have dropped or refused some: counted there).
  merged_.add_problems(camera_stats_);
  return merged_;
}

}  // namespace rtslam::io
