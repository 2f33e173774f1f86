#include "rtslam/io/camera_source.hpp"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <mutex>
#include <variant>

#include <fmt/format.h>
#include <opencv2/videoio.hpp>  // cv::CAP_*

#include "rtslam/core/error.hpp"

namespace rtslam::io {

namespace fs = std::filesystem;

namespace {

bool all_digits(const std::string& s) {
  if (s.empty() || s.size() > 3) return false;
  for (char c : s)
    if (c < '0' || c > '9') return false;
  return true;
}

}  // namespace

TimeNs steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

CameraSpec CameraSpec::parse(const std::string& spec) {
  CameraSpec c;
  constexpr std::string_view kDev = "/dev/video";
  if (all_digits(spec)) {
    c.is_device = true;
    c.index = std::stoi(spec);
    c.path = fmt::format("{}{}", kDev, c.index);
    return c;
  }
  if (spec.compare(0, kDev.size(), kDev) == 0 && all_digits(spec.substr(kDev.size()))) {
    c.is_device = true;
    c.index = std::stoi(spec.substr(kDev.size()));
    c.path = spec;
    return c;
  }
  if (fs::is_regular_file(spec)) {
    c.path = spec;
    return c;
  }
  throw ConfigError(fmt::format("camera:{}: not a camera (give its number N for /dev/videoN, or /dev/videoN) nor a "
                                "video file standing in for one",
                                spec));
}

TimeNs camera_frame_time(double driver_ms, TimeNs grab_ns, TimeNs previous_ns) {
  if (driver_ms > 0.0 && std::isfinite(driver_ms) && driver_ms < 9.2e12) {
    const auto driver_ns = static_cast<TimeNs>(std::llround(driver_ms * 1e6));
    if (driver_ns <= grab_ns + 1'000'000 && driver_ns >= grab_ns - kNsPerSecond && driver_ns > previous_ns) {
      return driver_ns;
    }
  }
  return grab_ns > previous_ns ? grab_ns : previous_ns + 1;
}

CameraSource::CameraSource(const CameraSpec& spec, cv::Size expected_size, double rate_hz, BadInputPolicy policy)
    : spec_(spec), expected_size_(expected_size), rate_hz_(rate_hz), reporter_(policy, stats_) {
  if (spec_.is_device) {
    if (!fs::exists(spec_.path)) {
      throw IoError(fmt::format("{}: no such camera device (camera:{}); `v4l2-ctl --list-devices` lists them",
                                spec_.path, spec_.index));
    }
    capture_ = codecs::open_camera(spec_.index, cv::CAP_V4L2);
    if (!capture_) {
      throw IoError(fmt::format("{}: cannot open the camera through OpenCV's V4L2 backend (busy, no permission, or "
                                "not a capture device)",
                                spec_.path));
    }
    if (expected_size_.width > 0 && expected_size_.height > 0) {
      capture_->set(cv::CAP_PROP_FRAME_WIDTH, expected_size_.width);
      capture_->set(cv::CAP_PROP_FRAME_HEIGHT, expected_size_.height);
    }
    if (rate_hz_ > 0.0) capture_->set(cv::CAP_PROP_FPS, rate_hz_);
    const double fps = capture_->get(cv::CAP_PROP_FPS);
    rate_hz_ = fps > 0.0 && std::isfinite(fps) ? fps : rate_hz_;
    return;
  }
  // The stand-in: the file's own reader (its errors name the file), frames at their presentation times or i / rate.
  given_rate_hz_ = rate_hz_;
  video_ = open_pass(nullptr);
  rate_hz_ = video_->rate_hz();
}

std::unique_ptr<VideoSource> CameraSource::open_pass(const SourceStats* before) const {
  // The end of a pass is no truncation (it starts the next one); the problems of the earlier passes are counted on.
  VideoSource::Options o;
  o.judge_end = false;
  o.continue_from = before;
  return std::make_unique<VideoSource>(spec_.path, given_rate_hz_, 0, cv::Size(), reporter_.policy(), o);
}

void CameraSource::interrupt() {
  {
    std::lock_guard<std::mutex> lock(wait_mu_);
    interrupted_ = true;
  }
  wait_cv_.notify_all();
}

CameraSource::~CameraSource() = default;

const SourceStats& CameraSource::stats() const {
  if (spec_.is_device) return stats_;
  merged_ = stats_;
  merged_.add_problems(video_->stats());  // (every pass's: each counts on from the one before)
  return merged_;
}

ImageFrame CameraSource::next_file_frame(TimeNs& due_ns) {
  while (true) {
    std::optional<Measurement> m = video_->next();
    if (m) {
      auto* f = std::get_if<ImageFrame>(&*m);
      if (f == nullptr) continue;  // (a video holds images only)
      if (!pass_first_t_) pass_first_t_ = f->t;
      pass_last_t_ = f->t;
      due_ns = *start_ns_ + pass_start_ns_ + (f->t - *pass_first_t_);
      return std::move(*f);
    }
    if (!pass_first_t_) {
      throw IoError(fmt::format("{}: no usable frame could be read from the video{}", spec_.path,
                                loops_ == 0 ? "" : " on reading it again from its start"));
    }
    // The end of the file: from its start again (reopened: not every backend can seek back), one nominal interval
    // after this pass's last frame. (Replaced once the new pass is open: a failure keeps the counts so far.)
    video_ = open_pass(&video_->stats());
    ++loops_;
    pass_start_ns_ += (pass_last_t_ - *pass_first_t_) + from_seconds(1.0 / rate_hz_);
    pass_first_t_.reset();
  }
}

std::optional<Measurement> CameraSource::next() {
  int skipped = 0;
  // A frame skipped (reported as bad input first: under the error policy that throws).
  const auto skip = [&](std::size_t SourceStats::*counter, const std::string& message, bool file_problem) {
    reporter_.report(counter, message, file_problem);
    if (++skipped >= kMaxSkippedInARow) {
      throw IoError(fmt::format("{}: {} frames in a row could not be used (the last: {}); check the device's "
                                "format and the calibration's image size",
                                spec_.path, skipped, message));
    }
  };
  while (true) {
    cv::Mat raw;
    TimeNs grab_ns = 0;
    double driver_ms = 0.0;
    if (spec_.is_device) {
      if (!capture_->grab()) {
        throw IoError(fmt::format("{}: the camera stopped delivering frames after {} (unplugged?)", spec_.path,
                                  index_));
      }
      grab_ns = steady_now_ns();
      driver_ms = capture_->get(cv::CAP_PROP_POS_MSEC);
      if (!capture_->retrieve(raw) || raw.empty()) {
        skip(&SourceStats::undecodable_images, fmt::format("{}#{}: the frame could not be retrieved", spec_.path,
                                                           index_++), true);
        continue;
      }
    } else {
      // A device delivers each frame when its time comes: so does the stand-in (its file decoded before the wait).
      if (!start_ns_) start_ns_ = steady_now_ns();
      TimeNs due = 0;
      ImageFrame f = next_file_frame(due);
      {
        // Until the frame is due, or interrupt() (a stopped run need not wait out a long gap in the file).
        std::unique_lock<std::mutex> lock(wait_mu_);
        const std::chrono::steady_clock::time_point until{std::chrono::nanoseconds(due)};
        wait_cv_.wait_until(lock, until, [this] { return interrupted_; });
        if (interrupted_) return std::nullopt;
      }
      grab_ns = steady_now_ns();
      raw = std::move(f.image);  // already 8-bit grey (to_grey8 below keeps it)
    }
    ImageFrame frame;
    frame.t = camera_frame_time(driver_ms, grab_ns, previous_ns_);
    previous_ns_ = frame.t;
    frame.path = fmt::format("{}#{}", spec_.path, index_++);
    std::string why;
    frame.image = to_grey8(raw, &why, &image_bits_);
    if (frame.image.empty()) {
      skip(&SourceStats::unsupported_images, fmt::format("{}: frame {}", frame.path, why), true);
      continue;
    }
    if (expected_size_.width > 0 && expected_size_.height > 0 && frame.image.size() != expected_size_) {
      skip(&SourceStats::wrong_size_images,
           fmt::format("{}: frame is {}x{}, the calibration says {}x{}", frame.path, frame.image.cols,
                       frame.image.rows, expected_size_.width, expected_size_.height),
           false);
      continue;
    }
    ++stats_.images;
    return frame;
  }
}

}  // namespace rtslam::io
