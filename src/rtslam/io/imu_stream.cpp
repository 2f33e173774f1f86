#include "rtslam/io/imu_stream.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>

#include <fcntl.h>
#include <poll.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/io/camera_source.hpp"  // steady_now_ns
#include "rtslam/io/live_source.hpp"
#include "rtslam/io/text.hpp"

namespace rtslam::io {

namespace {

/// The numbers of a line, separated by commas and/or blanks; false when a field is not a number.
bool parse_fields(std::string_view line, std::vector<double>& values, std::int64_t& first_int, bool& first_is_int) {
  values.clear();
  first_is_int = false;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ',' || line[i] == ' ' || line[i] == '\t')) ++i;
    if (i >= line.size()) break;
    std::size_t j = i;
    while (j < line.size() && line[j] != ',' && line[j] != ' ' && line[j] != '\t') ++j;
    const std::string_view f = line.substr(i, j - i);
    if (values.empty()) first_is_int = parse_int64(f, first_int);
    double v = 0.0;
    if (!parse_double(f, v)) return false;
    values.push_back(v);
    i = j;
  }
  return true;
}

std::string errno_text(int e) { return std::strerror(e); }

}  // namespace

ImuStreamClock imu_stream_clock_from_string(const std::string& s, const std::string& where) {
  if (s == "host") return ImuStreamClock::Host;
  if (s == "device") return ImuStreamClock::Device;
  throw ConfigError(fmt::format("{}: '{}' is not an IMU stream clock (host: times on this machine's CLOCK_MONOTONIC; "
                                "device: the IMU's own clock)",
                                where, s));
}

ImuStreamReader::ImuStreamReader(std::string path, const Options& options)
    : path_(std::move(path)), options_(options) {
  if (path_.empty()) throw ConfigError("IMU stream: empty path (a FIFO, a serial device, a file, or - for stdin)");
  if (path_ == "-") {
    fd_ = ::dup(STDIN_FILENO);
    if (fd_ < 0) throw IoError(fmt::format("-: cannot read standard input as the IMU stream ({})", errno_text(errno)));
    ::fcntl(fd_, F_SETFD, FD_CLOEXEC);
  } else {
    std::error_code ec;  // (an unreadable path is for open() below to report)
    if (std::filesystem::is_directory(path_, ec)) {
      throw IoError(fmt::format("{}: a folder, not an IMU stream (a FIFO, a serial device, a file, or - for stdin)",
                                path_));
    }
    fd_ = ::open(path_.c_str(), O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
    if (fd_ < 0) {
      const int e = errno;
      const char* hint = e == ENOENT ? "; create a FIFO with mkfifo, or give a serial device, a file or -" : "";
      throw IoError(fmt::format("{}: cannot open the IMU stream ({}{})", path_, errno_text(e), hint));
    }
  }
  struct stat st {};
  is_device_ = ::fstat(fd_, &st) == 0 && S_ISCHR(st.st_mode) && ::isatty(fd_) == 1;
  skipping_first_fragment_ = is_device_;  // opened in the middle of its flow: the first bytes are a line's tail
  if (is_device_) {
    // Raw bytes (its speed kept: set with stty): no echo back to the device, no CR->NL mapping, no line editing or
    // end-of-file byte.
    termios tio{};
    if (::tcgetattr(fd_, &tio) == 0) {
      saved_termios_ = std::make_unique<termios>(tio);  // restored by the destructor (a terminal on stdin: the user's)
      ::cfmakeraw(&tio);
      tio.c_cc[VMIN] = 1;
      tio.c_cc[VTIME] = 0;
      ::tcsetattr(fd_, TCSANOW, &tio);
    }
  }
  if (::pipe2(wake_, O_CLOEXEC | O_NONBLOCK) != 0) {
    const int e = errno;
    ::close(fd_);
    throw IoError(fmt::format("{}: cannot create the IMU reader's wake-up pipe ({})", path_, errno_text(e)));
  }
}

ImuStreamReader::~ImuStreamReader() {
  if (saved_termios_ && fd_ >= 0) ::tcsetattr(fd_, TCSANOW, saved_termios_.get());
  if (fd_ >= 0) ::close(fd_);
  for (int fd : wake_)
    if (fd >= 0) ::close(fd);
}

void ImuStreamReader::interrupt() {
  interrupted_ = true;
  const char c = 1;
  [[maybe_unused]] const ssize_t n = ::write(wake_[1], &c, 1);  // full pipe: a wake-up is pending already
}

bool ImuStreamReader::run(LiveSource& live) {
  char buf[4096];
  while (!interrupted_) {
    pollfd fds[2] = {{fd_, POLLIN, 0}, {wake_[0], POLLIN, 0}};
    const int r = ::poll(fds, 2, -1);
    if (r < 0) {
      if (errno == EINTR) continue;
      throw IoError(fmt::format("{}: waiting for the IMU stream failed ({})", path_, errno_text(errno)));
    }
    if (interrupted_ || (fds[1].revents & POLLIN) != 0) return false;
    if ((fds[0].revents & (POLLIN | POLLHUP | POLLERR)) == 0) continue;
    const ssize_t n = ::read(fd_, buf, sizeof buf);
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) continue;
    if (n < 0) {
      throw IoError(fmt::format("{}: reading the IMU stream failed after {} lines ({}{})", path_, line_,
                                errno_text(errno), is_device_ ? ": unplugged?" : ""));
    }
    if (n == 0 && is_device_) {
      // A serial device does not end: it hung up (unplugged). A terminal in canonical mode also returns 0 for an
      // end-of-file byte (0x04, e.g. in noise at a wrong baud rate): no hang-up then, reading goes on.
      if ((fds[0].revents & POLLHUP) == 0) continue;
      throw IoError(fmt::format("{}: the IMU device stopped after {} lines (hung up: unplugged?)", path_, line_));
    }
    const TimeNs read_ns = steady_now_ns();
    if (n == 0) {  // the writer closed the stream (a FIFO's, standard input's or a file's end)
      finish(read_ns, live);
      return true;
    }
    feed(buf, static_cast<std::size_t>(n), read_ns, live);
  }
  return false;
}

void ImuStreamReader::feed(const char* data, std::size_t size, TimeNs read_ns, LiveSource& live) {
  batch_.clear();
  batch_read_ns_ = read_ns;
  for (std::size_t k = 0; k < size; ++k) {
    const char c = data[k];
    if (c == '\n') {
      if (skipping_first_fragment_) {
        skipping_first_fragment_ = false;
      } else if (!skipping_long_line_) {
        parse_line(pending_, live, batch_);
      }
      skipping_long_line_ = false;
      pending_.clear();
    } else if (skipping_first_fragment_ || !skipping_long_line_) {
      // No newline in sight after kMaxLineLength bytes (the first fragment's included): not a text IMU stream, or a
      // serial port at the wrong baud rate. The line is reported once and skipped to its end.
      std::size_t length = 0;
      if (skipping_first_fragment_) {
        length = ++fragment_bytes_;
      } else {
        pending_.push_back(c);
        length = pending_.size();
      }
      if (length > kMaxLineLength) {
        skipping_first_fragment_ = false;
        skipping_long_line_ = true;
        pending_.clear();
        ++line_;
        // Under the error policy this line ends the stream: the lines before it are pushed first. (Otherwise the
        // read's lines are stamped together: the device clock's offset comes from the latest of them.)
        if (live.problems_end_the_stream()) push_batch(batch_, read_ns, live);
        live.report_problem(&SourceStats::malformed_lines,
                            fmt::format("{}:{}: a line longer than {} characters (binary data, or a serial port at "
                                        "the wrong baud rate?)",
                                        path_, line_, kMaxLineLength),
                            true);
      }
    }
  }
  push_batch(batch_, read_ns, live);
}

void ImuStreamReader::finish(TimeNs read_ns, LiveSource& live) {
  batch_.clear();
  batch_read_ns_ = read_ns;
  if (!pending_.empty() && !skipping_long_line_ && !skipping_first_fragment_) parse_line(pending_, live, batch_);
  pending_.clear();
  push_batch(batch_, read_ns, live);
}

void ImuStreamReader::parse_line(const std::string& raw, LiveSource& live, std::vector<ParsedLine>& batch) {
  ++line_;
  std::string_view line = trim(raw);
  if (!line.empty() && line.back() == '\r') line = trim(line.substr(0, line.size() - 1));
  if (line.empty() || line.front() == '#') return;
  std::vector<double>& v = fields_;
  std::int64_t t_int = 0;
  bool t_is_int = false;
  const bool numbers = parse_fields(line, v, t_int, t_is_int);
  if (!numbers && !seen_data_line_) {  // a header line (`timestamp,w_x,...`) before the first sample
    seen_data_line_ = true;
    return;
  }
  seen_data_line_ = true;
  if (!numbers || v.size() != 7 || !t_is_int) {
    if (live.problems_end_the_stream()) push_batch(batch, batch_read_ns_, live);  // (as for an over-long line)
    live.report_problem(&SourceStats::malformed_lines,
                        fmt::format("{}:{}: expected 7 numbers 'timestamp [ns], w_x, w_y, w_z, a_x, a_y, a_z', got "
                                    "'{}'",
                                    path_, line_, std::string(line.substr(0, 200))),
                        true);
    return;
  }
  ParsedLine p;
  p.line = line_;
  p.time = t_int;
  p.sample.gyro = Eigen::Vector3d(v[1], v[2], v[3]);
  p.sample.accel = Eigen::Vector3d(v[4], v[5], v[6]);
  batch.push_back(p);
}

bool ImuStreamReader::consistent(TimeNs time, TimeNs read_ns, std::optional<TimeNs> previous,
                                 TimeNs previous_read_ns) const {
  const double t = to_seconds(time), now = to_seconds(read_ns);  // (in double: any int64 time is allowed)
  if (options_.clock == ImuStreamClock::Host) {
    // On the clock when read: not in its future, not older than a backlog can be.
    if (t > now + kMaxHostLeadS || t < now - kMaxHostAgeS) return false;
  } else if (time < 0) {
    return false;
  }
  if (!previous) return true;
  // Advanced since the previous line by at most the time that passed between their reads, plus kMaxJumpS.
  return t - to_seconds(*previous) <= now - to_seconds(previous_read_ns) + kMaxJumpS;
}

void ImuStreamReader::push_batch(std::vector<ParsedLine>& batch, TimeNs read_ns, LiveSource& live) {
  if (batch.empty()) return;
  const bool device = options_.clock == ImuStreamClock::Device;
  // Each line's time against the stream so far: order, and plausibility (consistent()). A line that fails is bad
  // input and leaves the stream's state alone (one corrupt time would otherwise make every later line "backwards");
  // kReanchorLines failing lines in a row that agree with one another (the stream's first time was the corrupt one,
  // or the device's counter restarted) become the stream's new reference.
  TimeNs latest = 0;
  bool any = false;
  for (ParsedLine& p : batch) {
    p.accepted = false;
    const bool ordered = !last_time_ || p.time > *last_time_;
    if (!ordered || !consistent(p.time, read_ns, last_time_, last_read_ns_)) {
      const bool follows_run =
          run_length_ > 0 && p.time > run_last_ && consistent(p.time, read_ns, run_last_, run_read_ns_);
      run_length_ = follows_run ? run_length_ + 1 : (consistent(p.time, read_ns, std::nullopt, 0) ? 1 : 0);
      run_last_ = p.time;
      run_read_ns_ = read_ns;
      if (run_length_ < kReanchorLines) {
        const std::string at = fmt::format("{}:{}", path_, p.line);
        const std::string what = device ? "device time" : "sample time";
        if (!ordered) {
          const bool same = p.time == *last_time_;
          live.report_problem(same ? &SourceStats::duplicate_timestamps : &SourceStats::backwards_timestamps,
                              fmt::format("{}: {} {} ns {} (previous {} ns)", at, what, p.time,
                                          same ? "repeats" : "goes backwards", *last_time_));
        } else if (device || !consistent(p.time, read_ns, std::nullopt, 0)) {
          live.report_problem(
              &SourceStats::timestamp_jumps,
              device ? fmt::format("{}: device time {} ns jumps ahead of the previous {} ns (corrupt?)", at, p.time,
                                   last_time_.value_or(0))
                     : fmt::format("{}: sample time {} s is {:.3g} s from this machine's CLOCK_MONOTONIC ({} s) when "
                                   "read: corrupt, or not stamped with clock_gettime(CLOCK_MONOTONIC) in ns (the "
                                   "IMU's own clock: --imu-clock device)",
                                   at, format_seconds(p.time), to_seconds(p.time) - to_seconds(read_ns),
                                   format_seconds(read_ns)));
        } else {
          live.report_problem(&SourceStats::timestamp_jumps,
                              fmt::format("{}: sample time {} s jumps ahead of the previous {} s (corrupt?)", at,
                                          format_seconds(p.time), format_seconds(last_time_.value_or(0))));
        }
        continue;
      }
      logger("io")->warn("{}:{}: {} lines in a row agree with one another but not with the stream before them: "
                         "their times are the stream's reference from here on",
                         path_, p.line, kReanchorLines);
      if (device) {  // a new device clock: its delay is measured afresh
        window_start_.reset();
        current_min_.reset();
        previous_min_.reset();
      }
    }
    run_length_ = 0;
    p.accepted = true;
    last_time_ = p.time;
    last_read_ns_ = read_ns;
    latest = p.time;  // (increasing)
    any = true;
  }
  if (!any) {
    batch.clear();
    return;
  }
  if (device) {
    // The lines read at once were sent over time: the latest of them bounds the delay best. The smallest delay of
    // the current and the previous window is the offset (older ones are forgotten: the two clocks drift apart).
    const TimeNs offset = read_ns - latest;  // (both >= 0: no overflow)
    if (!window_start_ || read_ns - *window_start_ >= kOffsetWindowNs) {
      // A new window; after a pause of more than one window the previous minimum is stale too.
      previous_min_ = window_start_ && read_ns - *window_start_ < 2 * kOffsetWindowNs ? current_min_ : std::nullopt;
      current_min_.reset();
      window_start_ = read_ns;
    }
    if (!current_min_ || offset < *current_min_) current_min_ = offset;
    offset_ns_ = previous_min_ ? std::min(*previous_min_, *current_min_) : *current_min_;
  }
  for (ParsedLine& p : batch) {
    if (!p.accepted) continue;
    ImuSample& s = p.sample;
    const std::string at = fmt::format("{}:{}", path_, p.line);
    if (device) {
      s.t = p.time + offset_ns_;  // within [read - (latest - time) - window drift, read]: no overflow
      // A delay estimate that just shrank would move the sample before the previous one: it is placed just after.
      if (have_last_ && s.t <= last_t_) s.t = last_t_ + 1;
    } else {
      s.t = p.time;
    }
    if (const std::string problem = imu_range_problem(s, options_.range); !problem.empty()) {
      live.report_problem(&SourceStats::imu_saturated, fmt::format("{}: {}", at, problem));
      continue;
    }
    if (have_last_ && options_.rate_hz > 0.0 && s.t > last_t_) {
      const double gap_s = to_seconds(s.t - last_t_);
      const double missing = std::round(gap_s * options_.rate_hz) - 1.0;
      if (missing > options_.max_dropout) {
        live.report_problem(&SourceStats::imu_gaps,
                            fmt::format("{}: IMU gap of {:.3f} s before t = {} s (~{:.0f} samples missing, more than "
                                        "{})",
                                        at, gap_s, format_seconds(s.t), missing, options_.max_dropout));
      }
    }
    if (!have_last_ || s.t > last_t_) {
      last_t_ = s.t;
      have_last_ = true;
    }
    live.push_imu(s);
  }
  batch.clear();
}

}  // namespace rtslam::io
