#pragma once
// Live input (`rtslam run --dataset camera:N`, docs/datasets.md "Live camera"): a V4L2 camera read through OpenCV's
// VideoCapture (V4L2 backend), or a video file standing in for one (`camera:FILE`: the file is played in a loop,
// each frame released by the wall clock when its time in the file comes, as a device would deliver it; the tests use
// it on machines without a camera). The stream is endless: a run ends with --stop-after (seconds of input), Ctrl-C,
// or a device error.
//
// Timestamps (TimeNs on std::chrono::steady_clock, i.e. CLOCK_MONOTONIC on Linux): for a device, the driver's buffer
// timestamp when it is plausible (camera_frame_time below), else the steady clock right after the grab; for the
// stand-in file, the steady clock when the frame is released. The stand-in reads the file through VideoSource: its
// frames come at their presentation times (a variable frame rate keeps its intervals) or at i / rate when a rate is
// given, each pass starting one nominal interval after the previous pass's last frame. Frames are converted to 8-bit
// grey (to_grey8). The calibration (io::Rig, from --calibration: the existing loaders) gives the expected image
// size, which is asked of the device; frames of another size are bad input (wrong_size_images). No IMU: a live IMU
// stream is paired with it by LiveRigSource (live_rig.hpp).
#include <condition_variable>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "rtslam/core/time.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::io {

/// Which device "camera:SPEC" names: a V4L2 index ("0", "/dev/video0") or a video file standing in for one.
struct CameraSpec {
  bool is_device = false;
  int index = -1;     // /dev/video<index> when a device
  std::string path;   // "/dev/videoN", or the video file
  /// Parses SPEC (the part after "camera:"); throws ConfigError naming it when it is neither a device number, a
  /// /dev/videoN path nor an existing file.
  static CameraSpec parse(const std::string& spec);
};

/// The steady clock now, in ns: the clock live frames (and a host-stamped IMU stream, imu_stream.hpp) are stamped on.
TimeNs steady_now_ns();

/// The timestamp of a frame grabbed at `grab_ns` (steady clock) whose driver reported `driver_ms` (OpenCV's
/// CAP_PROP_POS_MSEC: with the V4L2 backend the v4l2_buffer timestamp, CLOCK_MONOTONIC for UVC and most drivers;
/// <= 0 when none). The driver's time is taken when it is plausible on the same clock: at most 1 ms after the grab,
/// at most 1 s before it, and after the previous frame's `previous_ns`; otherwise the grab time (always after
/// `previous_ns`: the stream's times strictly increase).
TimeNs camera_frame_time(double driver_ms, TimeNs grab_ns, TimeNs previous_ns);

class CameraSource final : public Source {
 public:
  /// Frames skipped in a row (--bad-input skip: unretrievable, unconvertible or of the wrong size) after which the
  /// camera is taken to deliver nothing usable: an IoError naming the last reason, rather than a run that waits
  /// forever (at 30 Hz, about 3 s).
  static constexpr int kMaxSkippedInARow = 100;

  /// `expected_size`: the calibration's image size (asked of a device; 0x0: unchecked). `rate_hz`: asked of a device,
  /// and the stand-in file's playback rate (frames at i / rate; 0: the device's own rate / the file's own times).
  CameraSource(const CameraSpec& spec, cv::Size expected_size, double rate_hz, BadInputPolicy policy);
  ~CameraSource() override;
  CameraSource(const CameraSource&) = delete;
  CameraSource& operator=(const CameraSource&) = delete;

  std::optional<Measurement> next() override;
  /// The stand-in's wait for its next frame ends at once, and next() returns the end (a device's grab is not
  /// interrupted: it delivers a frame every period).
  void interrupt() override;
  /// The frames delivered and every problem met (the stand-in's: over all its passes through the file).
  const SourceStats& stats() const override;
  /// The rate the source delivers at (the device's reported rate; the stand-in's given rate, else the file's nominal
  /// one: VideoSource::rate_hz; 0: unknown).
  double rate_hz() const { return rate_hz_; }
  /// Times the stand-in file was rewound to its start.
  std::size_t loops() const { return loops_; }

 private:
  /// The stand-in's next frame (converted to grey by VideoSource) and the steady-clock time it is due at; a new pass
  /// from the file's start at its end. Throws IoError when a whole pass gave no frame.
  ImageFrame next_file_frame(TimeNs& due_ns);
  /// A pass through the stand-in's file, counting on from the problems `before` (the previous pass's).
  std::unique_ptr<VideoSource> open_pass(const SourceStats* before) const;

  CameraSpec spec_;
  cv::Size expected_size_;
  double rate_hz_ = 0.0;
  double given_rate_hz_ = 0.0;  // the stand-in's rate option (0: its file's own times)
  SourceStats stats_;
  BadInputReporter reporter_;
  std::unique_ptr<codecs::VideoReader> capture_;  // a device
  std::unique_ptr<VideoSource> video_;         // the stand-in's current pass through its file
  mutable SourceStats merged_;                 // stats() of the stand-in: its own and its passes' (video_'s)
  TimeNs pass_start_ns_ = 0;                   // the current pass's first frame: time after start_ns_
  std::optional<TimeNs> pass_first_t_;         // its time in the file
  TimeNs pass_last_t_ = 0;                     // the time in the file of the last frame of the current pass
  std::size_t index_ = 0;
  std::size_t loops_ = 0;
  int image_bits_ = 8;
  TimeNs previous_ns_ = 0;
  std::optional<TimeNs> start_ns_;  // the stand-in's pacing origin (steady clock when its first frame was due)
  std::mutex wait_mu_;              // the stand-in's wait for a frame's time, ended by interrupt()
  std::condition_variable wait_cv_;
  bool interrupted_ = false;
};

}  // namespace rtslam::io
