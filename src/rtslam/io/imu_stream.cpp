#include "rtslam/io/imu_stream.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>

#include <fcntl.h>
#include <poll.h>
#include <sys/stat.h>
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
    if (std::filesystem::is_directory(path_)) {
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
  if (::pipe2(wake_, O_CLOEXEC | O_NONBLOCK) != 0) {
    const int e = errno;
    ::close(fd_);
    throw IoError(fmt::format("{}: cannot create the IMU reader's wake-up pipe ({})", path_, errno_text(e)));
  }
}

ImuStreamReader::~ImuStreamReader() {
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
  std::string pending;
  char buf[4096];
  bool skipping_long_line = false;
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
    if (n < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) continue;
      throw IoError(fmt::format("{}: reading the IMU stream failed ({})", path_, errno_text(errno)));
    }
    const TimeNs read_ns = steady_now_ns();
    if (n == 0) {  // the writer closed the stream (or a file's end): a last line without its newline counts
      if (!pending.empty() && !skipping_long_line) handle_line(pending, read_ns, live);
      return true;
    }
    for (ssize_t k = 0; k < n; ++k) {
      const char c = buf[k];
      if (c == '\n') {
        if (!skipping_long_line) handle_line(pending, read_ns, live);
        skipping_long_line = false;
        pending.clear();
      } else if (!skipping_long_line) {
        pending.push_back(c);
        if (pending.size() > kMaxLineLength) {  // no newline in sight: not a text IMU stream (or a wrong baud rate)
          ++line_;
          live.report_problem(&SourceStats::malformed_lines,
                              fmt::format("{}:{}: a line longer than {} characters (binary data, or a serial port at "
                                          "the wrong baud rate?)",
                                          path_, line_, kMaxLineLength),
                              true);
          skipping_long_line = true;
          pending.clear();
        }
      }
    }
  }
  return false;
}

void ImuStreamReader::handle_line(const std::string& raw, TimeNs read_ns, LiveSource& live) {
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
  const bool timeless = options_.clock == ImuStreamClock::Device && v.size() == 6;
  if (!numbers || !(v.size() == 7 || timeless) || (v.size() == 7 && !t_is_int)) {
    const char* or_six = options_.clock == ImuStreamClock::Device ? " (or the 6 readings)" : "";
    live.report_problem(&SourceStats::malformed_lines,
                        fmt::format("{}:{}: expected 7 numbers 'timestamp [ns], w_x, w_y, w_z, a_x, a_y, a_z'{}, got "
                                    "'{}'",
                                    path_, line_, or_six, std::string(line.substr(0, 200))),
                        true);
    return;
  }
  ImuSample s;
  const std::size_t o = timeless ? 0 : 1;
  s.gyro = Eigen::Vector3d(v[o], v[o + 1], v[o + 2]);
  s.accel = Eigen::Vector3d(v[o + 3], v[o + 4], v[o + 5]);
  if (options_.clock == ImuStreamClock::Host) {
    s.t = t_int;
    if (!checked_clock_) {
      checked_clock_ = true;
      const double skew_s = to_seconds(read_ns - s.t);
      if (!(std::abs(skew_s) <= kMaxHostSkewS)) {
        throw ConfigError(fmt::format(
            "{}:{}: the first sample's time {} s is {:.3g} s away from this machine's CLOCK_MONOTONIC ({} s) when it "
            "was read: stamp the samples with clock_gettime(CLOCK_MONOTONIC) in ns, or give --imu-clock device",
            path_, line_, format_seconds(s.t), skew_s, format_seconds(read_ns)));
      }
    }
  } else if (timeless) {
    s.t = read_ns;
  } else {
    const TimeNs offset = read_ns - t_int;  // the delay plus the clocks' difference: its smallest value is the best
    if (!have_offset_ || offset < offset_ns_) offset_ns_ = offset;
    have_offset_ = true;
    s.t = t_int + offset_ns_;
  }
  if (options_.clock == ImuStreamClock::Device && have_last_ && s.t <= last_t_) {
    s.t = last_t_ + 1;  // read-time stamps of one burst, or a delay estimate that just shrank: kept in order
  }
  if (const std::string problem = imu_range_problem(s, options_.range); !problem.empty()) {
    live.report_problem(&SourceStats::imu_saturated, fmt::format("{}:{}: {}", path_, line_, problem));
    return;
  }
  if (have_last_ && options_.rate_hz > 0.0 && s.t > last_t_) {
    const double gap_s = to_seconds(s.t - last_t_);
    const double missing = std::round(gap_s * options_.rate_hz) - 1.0;
    if (missing > options_.max_dropout) {
      live.report_problem(&SourceStats::imu_gaps,
                          fmt::format("{}:{}: IMU gap of {:.3f} s before t = {} s (~{:.0f} samples missing, more than "
                                      "{})",
                                      path_, line_, gap_s, format_seconds(s.t), missing, options_.max_dropout));
    }
  }
  if (!have_last_ || s.t > last_t_) {
    last_t_ = s.t;
    have_last_ = true;
  }
  live.push_imu(s);
}

}  // namespace rtslam::io
