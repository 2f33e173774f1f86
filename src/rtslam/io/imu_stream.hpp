#pragma once
// A live IMU stream (`rtslam run --dataset camera:N --imu-stream PATH`, docs/datasets.md "Live camera with an IMU"):
// text lines `t[ns], w_x, w_y, w_z, a_x, a_y, a_z` (EuRoC imu0/data.csv's columns: rad/s, m/s²; commas or blanks
// between the numbers; '#' lines, blank lines and a header line skipped) read as they arrive from a FIFO, a character
// device (a serial port, set up with stty), standard input ("-") or a file. The stream ends when its writer closes it
// (the end of a FIFO, a file or standard input) or when interrupt() is called.
//
// Clock (ImuStreamClock): the camera's frames are stamped on the steady clock (CLOCK_MONOTONIC, camera_source.hpp).
//   Host:   t is the sample's time on that clock, in ns (a driver on the same machine stamping with
//           clock_gettime(CLOCK_MONOTONIC)): within kMaxHostLeadS after and kMaxHostAgeS before the clock when it is
//           read (a backlog queued in a pipe is old, a sample is never from the future; a driver stamping on another
//           clock fails on every line, each message says so).
//   Device: t is the IMU's own clock in ns (any origin ≥ 0: a microcontroller's counter), mapped onto the steady
//           clock by the smallest delay between a sample's device time and the time it was read, over the last two
//           windows of kOffsetWindowNs (the transport's latency at its fastest; older minima are forgotten, so the
//           two clocks may drift apart). Lines read at once share a read time, and the latest of them bounds the
//           delay: serial and USB links deliver in bursts, whose samples keep their device intervals. A delay
//           estimate that shrinks never moves a stamp before the previous one (it is then placed 1 ns after it).
// Every line's time must also follow the previous line's: later, and ahead of it by at most the time that passed
// between their reads plus kMaxJumpS. A line that fails is bad input (a corrupt time) and leaves the stream's state
// alone; kReanchorLines failing lines in a row that agree with one another (the stream's first time was the corrupt
// one, or the device's counter restarted) become its reference from there on (logged).
// A serial device (a tty) is put in raw mode (its speed kept) and is opened in the middle of its flow: the bytes up to
// the first newline are dropped. Its end (a hang-up: unplugged) is an IoError; the end of a FIFO, standard input or
// a file ends the stream (a file is read to its end at once, not followed as it grows).
// Checks, through the LiveSource the samples go to (its policy: skip and count, or stop with the error), each naming
// PATH:LINE: malformed lines; times that repeat, go backwards or are implausible (above; timestamp_jumps); readings
// beyond the sensor's range (ImuRange; non-finite ones too: imu_saturated); gaps of more than `max_dropout` missing
// samples at the calibration's rate (no gap check when the rate is unknown).
#include <atomic>
#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rtslam/io/source.hpp"

struct termios;

namespace rtslam::io {

class LiveSource;

enum class ImuStreamClock { Host, Device };

/// Parses "host" / "device" (ConfigError naming `where` otherwise).
ImuStreamClock imu_stream_clock_from_string(const std::string& s, const std::string& where);

class ImuStreamReader {
 public:
  static constexpr double kMaxHostLeadS = 1.0, kMaxHostAgeS = 60.0, kMaxJumpS = 5.0;
  static constexpr int kReanchorLines = 3;
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
  /// or a serial device's hang-up is thrown (IoError naming PATH).
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
  /// A line's time read at `read_ns` is plausible: on the host clock (Host), not negative (Device), and after
  /// `previous` (read at `previous_read_ns`) by at most the time between the reads plus kMaxJumpS.
  bool consistent(TimeNs time, TimeNs read_ns, std::optional<TimeNs> previous, TimeNs previous_read_ns) const;

  std::string path_;
  Options options_;
  int fd_ = -1;
  int wake_[2] = {-1, -1};  // a pipe whose write end interrupt() writes to: ends run()'s poll
  std::atomic<bool> interrupted_{false};
  long line_ = 0;
  bool is_device_ = false;  // a serial device (tty)
  std::unique_ptr<termios> saved_termios_;  // its settings before raw mode, restored at the end
  bool seen_data_line_ = false;
  // Failing lines in a row that agree with one another (re-anchoring): their number, the last one's time and read.
  int run_length_ = 0;
  TimeNs run_last_ = 0, run_read_ns_ = 0;
  std::size_t fragment_bytes_ = 0;  // of a serial device's first fragment, skipped
  // Device clock: steady clock − device clock, the smallest of the current and the previous window.
  TimeNs offset_ns_ = 0;
  std::optional<TimeNs> window_start_, current_min_, previous_min_;
  std::optional<TimeNs> last_time_;  // the previous accepted line's time as written
  TimeNs last_read_ns_ = 0;          // when it was read
  TimeNs last_t_ = 0;                // the previous sample's stamp (gap check, order of Device stamps)
  bool have_last_ = false;
  std::vector<double> fields_;      // parse_line's scratch
  std::vector<ParsedLine> batch_;   // the lines of one read (pushed early when a malformed line follows them)
  TimeNs batch_read_ns_ = 0;        // when that read was made
  std::string pending_;             // a line not yet ended by its newline
  bool skipping_long_line_ = false;
  bool skipping_first_fragment_ = false;
};

}  // namespace rtslam::io
