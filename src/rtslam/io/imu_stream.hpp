#pragma once
// A live IMU stream (`rtslam run --dataset camera:N --imu-stream PATH`, docs/datasets.md "Live camera with an IMU"):
// text lines `t[ns], w_x, w_y, w_z, a_x, a_y, a_z` (EuRoC imu0/data.csv's columns: rad/s, m/s²; commas or blanks
// between the numbers; '#' lines, blank lines and a header line skipped) read as they arrive from a FIFO, a character
// device (a serial port, set up with stty), standard input ("-") or a file. The stream ends when its writer closes it
// (the end of a FIFO, a file or standard input) or when interrupt() is called.
//
// Clock (ImuStreamClock): the camera's frames are stamped on the steady clock (CLOCK_MONOTONIC, camera_source.hpp).
//   Host:   t is the sample's time on that clock, in ns (a driver on the same machine stamping with
//           clock_gettime(CLOCK_MONOTONIC)). The first sample must lie within kMaxHostSkewS of the clock when it is
//           read, else ConfigError: the producer stamps on another clock, and every time would be wrong.
//   Device: t is the IMU's own clock in ns (any origin: a microcontroller's counter), mapped onto the steady clock by
//           the smallest delay seen so far between a sample's device time and the time its line was read (the
//           transport's latency, found by its fastest deliveries; serial and USB links deliver in bursts, so the read
//           time alone is a poor stamp). Lines of 6 numbers (no time) are stamped with the read time itself. Stamps
//           never go backwards: when the delay estimate shrinks, the samples it would move before the previous one
//           are placed 1 ns after it.
// Checks, through the LiveSource the samples go to (its policy: skip and count, or stop with the error): malformed
// lines (naming PATH:LINE), readings beyond the sensor's range (ImuRange), gaps of more than `max_dropout` missing
// samples at the calibration's rate (no gap check when the rate is unknown), and LiveSource's own (order, NaN).
#include <atomic>
#include <cstddef>
#include <string>
#include <vector>

#include "rtslam/io/source.hpp"

namespace rtslam::io {

class LiveSource;

enum class ImuStreamClock { Host, Device };

/// Parses "host" / "device" (ConfigError naming `where` otherwise).
ImuStreamClock imu_stream_clock_from_string(const std::string& s, const std::string& where);

class ImuStreamReader {
 public:
  static constexpr double kMaxHostSkewS = 5.0;
  static constexpr std::size_t kMaxLineLength = 4096;
  struct Options {
    ImuStreamClock clock = ImuStreamClock::Host;
    ImuRange range;
    double rate_hz = 0.0;  // nominal rate for the gap check (0: unknown, no check)
    int max_dropout = 3;   // more missing samples than this in a row is a gap
  };
  /// Opens PATH ("-": standard input) without blocking (a FIFO without a writer yet is waited for by run()); IoError
  /// naming PATH when it cannot be opened, or is a folder.
  ImuStreamReader(std::string path, const Options& options);
  ~ImuStreamReader();
  ImuStreamReader(const ImuStreamReader&) = delete;
  ImuStreamReader& operator=(const ImuStreamReader&) = delete;

  /// Reads lines until the stream ends or interrupt() is called, pushing each sample into `live` and reporting the
  /// problems there. Returns true at the stream's end (its writer closed it), false when interrupted. A read error
  /// or a clock mismatch is thrown (IoError / ConfigError naming PATH).
  bool run(LiveSource& live);
  /// Ends run() at once (thread-safe).
  void interrupt();
  const std::string& path() const { return path_; }
  /// Lines read so far (blank and comment lines included). Read it from run()'s thread, or after run() returned.
  long lines() const { return line_; }

 private:
  /// Parses one line (without its newline) and pushes its sample; `read_ns`: the steady clock when it was read.
  void handle_line(const std::string& line, TimeNs read_ns, LiveSource& live);

  std::string path_;
  Options options_;
  int fd_ = -1;
  int wake_[2] = {-1, -1};  // a pipe whose write end interrupt() writes to: ends run()'s poll
  std::atomic<bool> interrupted_{false};
  long line_ = 0;
  bool seen_data_line_ = false;
  bool checked_clock_ = false;
  bool have_offset_ = false;
  TimeNs offset_ns_ = 0;  // Device: steady clock − device clock (the smallest seen)
  TimeNs last_t_ = 0;     // the previous sample's stamp (gap check, order of Device stamps)
  bool have_last_ = false;
  std::vector<double> fields_;  // handle_line's scratch
};

}  // namespace rtslam::io
