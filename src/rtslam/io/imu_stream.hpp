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
//           the smallest delay between a sample's device time and the time it was read, over the last two windows of
//           kOffsetWindowNs (the transport's latency at its fastest; older minima are forgotten, so the two clocks
//           may drift apart). Lines read at once share a read time, and the latest of them bounds the delay: serial
//           and USB links deliver in bursts, whose samples keep their device intervals. A device time that does not
//           increase is bad input (a counter that wrapped or restarted); a delay estimate that shrinks never moves a
//           stamp before the previous one (it is then placed 1 ns after it).
// A serial device (a tty) is opened in the middle of its flow: the bytes up to the first newline are dropped. Its
// end (a hang-up: unplugged) is an IoError; the end of a FIFO, standard input or a file ends the stream.
// Checks, through the LiveSource the samples go to (its policy: skip and count, or stop with the error), each naming
// PATH:LINE: malformed lines; times that repeat or go backwards; implausible times (a host time more than
// kMaxHostSkewS from the clock when read; a device time, or a negative one, advanced by more than the time that
// passed plus kMaxHostSkewS: corrupt, or the clock reset), which leave the stream's state alone; readings beyond the
// sensor's range (ImuRange); gaps of more than `max_dropout` missing samples at the calibration's rate (no gap check
// when the rate is unknown); and LiveSource's own (NaN).
#include <atomic>
#include <cstddef>
#include <optional>
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
  static constexpr TimeNs kOffsetWindowNs = 10 * kNsPerSecond;
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
  /// run()'s handling of the bytes of one read() made at `read_ns` (steady clock): lines are split (a partial one
  /// kept for the next call), parsed, stamped and pushed. finish(): the stream's end (a last line without its
  /// newline). Public for tests, and for a caller with its own reading loop (not both at once).
  void feed(const char* data, std::size_t size, TimeNs read_ns, LiveSource& live);
  void finish(TimeNs read_ns, LiveSource& live);
  const std::string& path() const { return path_; }
  /// Lines read so far (blank and comment lines included). Read it from run()'s thread, or after run() returned.
  long lines() const { return line_; }

 private:
  struct ParsedLine {
    long line = 0;
    TimeNs time = 0;  // as written (host or device clock)
    ImuSample sample;
    bool accepted = false;  // its time passed the order and plausibility checks
  };
  /// Parses one line (without its newline) into `batch`; reports a malformed one.
  void parse_line(const std::string& line, LiveSource& live, std::vector<ParsedLine>& batch);
  /// Stamps and checks the lines of one read (read at `read_ns`, the steady clock) and pushes their samples.
  void push_batch(std::vector<ParsedLine>& batch, TimeNs read_ns, LiveSource& live);

  std::string path_;
  Options options_;
  int fd_ = -1;
  int wake_[2] = {-1, -1};  // a pipe whose write end interrupt() writes to: ends run()'s poll
  std::atomic<bool> interrupted_{false};
  long line_ = 0;
  bool is_device_ = false;  // a serial device (tty)
  bool seen_data_line_ = false;
  bool checked_clock_ = false;
  // Device clock: steady clock − device clock, the smallest of the current and the previous window.
  TimeNs offset_ns_ = 0;
  std::optional<TimeNs> window_start_, current_min_, previous_min_;
  std::optional<TimeNs> last_time_;  // the previous accepted line's time as written
  TimeNs last_read_ns_ = 0;          // when it was read
  TimeNs last_t_ = 0;                // the previous sample's stamp (gap check, order of Device stamps)
  bool have_last_ = false;
  std::vector<double> fields_;      // parse_line's scratch
  std::vector<ParsedLine> batch_;   // the lines of one read
  std::string pending_;             // a line not yet ended by its newline
  bool skipping_long_line_ = false;
  bool skipping_first_fragment_ = false;
};

}  // namespace rtslam::io
