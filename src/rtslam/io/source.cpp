#include "rtslam/io/source.hpp"

#include <algorithm>
#include <cmath>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <system_error>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>  // cv::CAP_*

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/io/image_header.hpp"
#include "rtslam/io/png_grey.hpp"
#include "rtslam/io/prefetch.hpp"
#include "rtslam/io/text.hpp"

namespace rtslam::io {
namespace fs = std::filesystem;

TimeNs time_of(const Measurement& m) {
  return std::visit([](const auto& x) { return x.t; }, m);
}

ImuRange ImuRange::from_full_scale(std::optional<double> gyro_saturation, std::optional<double> accel_saturation) {
  ImuRange r;
  if (gyro_saturation && *gyro_saturation > 0.0) r.gyro_rad_s = std::min(*gyro_saturation, kMaxPlausibleGyro);
  if (accel_saturation && *accel_saturation > 0.0) r.accel_m_s2 = std::min(*accel_saturation, kMaxPlausibleAccel);
  return r;
}

std::string imu_range_problem(const ImuSample& s, const ImuRange& range) {
  // A reading at the full scale is within the range; the relative slack absorbs the rounding of a full scale
  // converted between units (deg/s <-> rad/s) or written as text.
  constexpr double kSlack = 1.0 + 1e-9;
  constexpr const char* kAxis = "xyz";
  for (int k = 0; k < 3; ++k) {
    if (!(std::abs(s.gyro[k]) <= range.gyro_rad_s * kSlack)) {
      return fmt::format("gyroscope w_{} = {:g} rad/s is beyond the sensor's range ±{:g} rad/s (saturated or corrupt)",
                         kAxis[k], s.gyro[k], range.gyro_rad_s);
    }
  }
  for (int k = 0; k < 3; ++k) {
    if (!(std::abs(s.accel[k]) <= range.accel_m_s2 * kSlack)) {
      return fmt::format(
          "accelerometer a_{} = {:g} m/s² is beyond the sensor's range ±{:g} m/s² (saturated or corrupt)", kAxis[k],
          s.accel[k], range.accel_m_s2);
    }
  }
  return {};
}

BadInputPolicy bad_input_policy_from_string(const std::string& s, const std::string& where) {
  if (s == "error") return BadInputPolicy::Error;
  if (s == "skip") return BadInputPolicy::Skip;
  throw ConfigError(fmt::format("{} = '{}' must be 'error' or 'skip'", where, s));
}

std::size_t SourceStats::problems() const {
  return backwards_timestamps + duplicate_timestamps + imu_gaps + non_finite + malformed_lines + missing_images +
         undecodable_images + wrong_size_images + imu_saturated + unsupported_images + timestamp_jumps;
}

namespace {

struct Counter {
  std::size_t SourceStats::*field;
  const char* singular;
  const char* plural;
  const char* key;
};

constexpr Counter kCounters[] = {
    {&SourceStats::backwards_timestamps, "backwards timestamp", "backwards timestamps", "backwards_timestamps"},
    {&SourceStats::duplicate_timestamps, "duplicate timestamp", "duplicate timestamps", "duplicate_timestamps"},
    {&SourceStats::imu_gaps, "IMU gap", "IMU gaps", "imu_gaps"},
    {&SourceStats::non_finite, "non-finite value", "non-finite values", "non_finite"},
    {&SourceStats::malformed_lines, "malformed line", "malformed lines", "malformed_lines"},
    {&SourceStats::missing_images, "missing image", "missing images", "missing_images"},
    {&SourceStats::undecodable_images, "undecodable image", "undecodable images", "undecodable_images"},
    {&SourceStats::wrong_size_images, "wrong-size image", "wrong-size images", "wrong_size_images"},
    {&SourceStats::imu_saturated, "IMU sample beyond the sensor's range", "IMU samples beyond the sensor's range",
     "imu_saturated"},
    {&SourceStats::unsupported_images, "image of an unsupported pixel type", "images of an unsupported pixel type",
     "unsupported_images"},
    {&SourceStats::timestamp_jumps, "timestamp jump", "timestamp jumps", "timestamp_jumps"},
};

}  // namespace

void SourceStats::add_problems(const SourceStats& other) {
  for (const auto& c : kCounters) this->*c.field += other.*c.field;
  live_dropped_images += other.live_dropped_images;
  live_dropped_imu_samples += other.live_dropped_imu_samples;
  live_images_before_imu += other.live_images_before_imu;
  for (const auto& m : other.messages) {
    if (messages.size() < kMaxMessages) messages.push_back(m);
  }
}

std::string SourceStats::summary() const {
  std::string s = fmt::format("{} images, {} IMU samples", images, imu_samples);
  std::string problems_text;
  for (const auto& c : kCounters) {
    const std::size_t n = this->*c.field;
    if (n == 0) continue;
    problems_text += fmt::format("{}{} {}", problems_text.empty() ? "" : ", ", n, n == 1 ? c.singular : c.plural);
  }
  if (!problems_text.empty()) s += "; bad input (skipped or noted): " + problems_text;
  if (live_dropped_images + live_dropped_imu_samples > 0) {
    s += fmt::format("; dropped by the live queue (the filter behind): {} images, {} IMU samples", live_dropped_images,
                     live_dropped_imu_samples);
  }
  if (live_images_before_imu > 0) s += fmt::format("; {} images before the IMU's first sample", live_images_before_imu);
  return s;
}

nlohmann::json SourceStats::to_json() const {
  nlohmann::json j;
  j["images"] = images;
  j["imu_samples"] = imu_samples;
  for (const auto& c : kCounters) j[c.key] = this->*c.field;
  j["live_dropped_images"] = live_dropped_images;
  j["live_dropped_imu_samples"] = live_dropped_imu_samples;
  j["live_images_before_imu"] = live_images_before_imu;
  j["messages"] = messages;
  return j;
}

void BadInputReporter::report(std::size_t SourceStats::*counter, const std::string& message, bool file_problem) {
  if (policy_ == BadInputPolicy::Error) {
    if (file_problem) throw IoError(message);
    throw DataError(message);
  }
  ++(stats_->*counter);
  const std::size_t n = stats_->problems();
  if (stats_->messages.size() < SourceStats::kMaxMessages) stats_->messages.push_back(message);
  if (n <= 20) {
    logger("io")->warn("skipped: {}", message);
  } else {
    logger("io")->debug("skipped: {}", message);
  }
}

namespace {

// One channel of 8- or 16-bit unsigned pixels at the image's own depth (see to_grey8); empty, `why` said, otherwise.
cv::Mat grey_channel(const cv::Mat& image, std::string* why) {
  const auto refuse = [why](std::string reason) {
    if (why) *why = "unsupported: " + std::move(reason);
    return cv::Mat();
  };
  if (image.empty()) return refuse("empty image");
  const int depth = image.depth();
  if (depth != CV_8U && depth != CV_16U) {
    const char* kind = depth == CV_32F || depth == CV_64F ? "floating-point" : "signed-integer";
    return refuse(fmt::format("{} pixels ({}-bit); give 8- or 16-bit unsigned images", kind, 8 * image.elemSize1()));
  }
  cv::Mat grey;
  switch (image.channels()) {
    case 1: grey = image; break;
    case 2: cv::extractChannel(image, grey, 0); break;  // grey + alpha
    case 3: cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY); break;
    case 4: cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY); break;
    default: return refuse(fmt::format("{} channels (1 to 4 accepted)", image.channels()));
  }
  return grey;
}

}  // namespace

cv::Mat to_grey8(const cv::Mat& image, std::string* why, int* bits) {
  const cv::Mat grey = grey_channel(image, why);
  if (grey.empty() || grey.depth() == CV_8U) return grey;
  double max_value = 0.0;
  cv::minMaxLoc(grey, nullptr, &max_value);
  int b = bits ? std::clamp(*bits, 8, 16) : 8;
  while (b < 16 && max_value >= static_cast<double>(1 << b)) b += 2;
  if (bits) *bits = b;
  cv::Mat out;
  grey.convertTo(out, CV_8U, 1.0 / static_cast<double>(1 << (b - 8)));
  // convertTo rounds; a value of 2^b - 1 scaled to 255.99 saturates at 255 as it should.
  return out;
}

cv::Mat decode_grey_image(const unsigned char* data, std::size_t size, std::string* why, int* bits, bool keep_16bit) {
  const auto fail = [why](std::string reason) {
    if (why) *why = "cannot be decoded: " + std::move(reason);
    return cv::Mat();
  };
  const auto header = read_image_header(data, size);
  if (!header) return fail("not a PNG, PNM, JPEG, BMP or TIFF image, or its header is truncated");
  if (const std::string problem = image_header_problem(*header); !problem.empty()) return fail("it " + problem);
  if (size > static_cast<std::size_t>(std::numeric_limits<int>::max())) return fail("larger than 2 GB");
  // 8-bit grey PNGs (the datasets' images) in half libpng's time, the same pixels; anything else goes to OpenCV.
  if (cv::Mat grey; header->format == ImageFormat::Png &&
                    decode_png_grey8(data, size, static_cast<std::size_t>(kMaxImagePixels), grey)) {
    return grey;
  }
  // A truncated PNG is refused here: libpng would print its own line ("PNG input buffer is incomplete") first.
  if (header->format == ImageFormat::Png && png_truncated(data, size)) {
    return fail("truncated PNG (its chunks end before IEND)");
  }
  // imdecode logs decoder errors (e.g. libpng "Read Error") itself; callers report the failure with the file name.
  // Decoded at the file's own depth and channels (IMREAD_GRAYSCALE alone would cut 16-bit pixels to their high byte:
  // a 16-bit file holding 8-bit values would be black), then converted by to_grey8.
  const cv::Mat bytes(1, static_cast<int>(size), CV_8UC1, const_cast<unsigned char*>(data));
  cv::Mat img;
  try {
    img = codecs::imdecode(bytes, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
  } catch (const cv::Exception&) {
    // imdecode throws (rather than returning an empty Mat) on some headers, e.g. a size beyond OpenCV's limits.
    return fail(fmt::format("{} header rejected by OpenCV", to_string(header->format)));
  }
  if (img.empty()) return fail(fmt::format("truncated or corrupt {}", to_string(header->format)));
  return keep_16bit && img.depth() == CV_16U ? grey_channel(img, why) : to_grey8(img, why, bits);
}

cv::Mat read_grey_image(const std::string& path, std::string* why, int* bits, bool keep_16bit) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    if (why) *why = "cannot be opened";
    return {};
  }
  // The largest image accepted, uncompressed at 8 bytes a pixel, plus room for metadata: nothing longer is read.
  constexpr std::uintmax_t kMaxBytes = 8 * static_cast<std::uintmax_t>(kMaxImagePixels) + (1u << 20);
  std::error_code ec;
  const auto file_bytes = fs::file_size(path, ec);
  if (!ec && file_bytes > kMaxBytes) {
    if (why) *why = fmt::format("cannot be decoded: {} bytes, larger than any image accepted", file_bytes);
    return {};
  }
  // Read in blocks into this thread's buffer, kept from image to image (the decoding threads read one file after
  // another: a fresh vector grown byte by byte through istreambuf_iterator cost more CPU than inflating the PNG).
  // The first block is the whole file and one byte more (a short read then means the end); then blocks of 64 KB
  // (a file that grew, or a pipe, whose size is unknown).
  thread_local std::vector<unsigned char> buffer;
  constexpr std::size_t kBlock = std::size_t{1} << 16;
  std::size_t size = 0;
  std::size_t block = !ec && file_bytes > 0 ? static_cast<std::size_t>(file_bytes) + 1 : kBlock;
  try {
    for (;;) {
      if (buffer.size() < size + block) buffer.resize(size + block);
      const auto got =
          in.rdbuf()->sgetn(reinterpret_cast<char*>(buffer.data() + size), static_cast<std::streamsize>(block));
      size += static_cast<std::size_t>(std::max<std::streamsize>(got, 0));
      if (size > kMaxBytes) {
        if (why) *why = fmt::format("cannot be decoded: more than {} bytes, larger than any image accepted", kMaxBytes);
        return {};
      }
      if (got < static_cast<std::streamsize>(block)) break;  // the end (sgetn reads short only there)
      block = kBlock;
    }
  } catch (const std::exception& e) {  // a read error (e.g. EIO, or a folder given as an image)
    if (why) *why = fmt::format("cannot be read: {}", e.what());
    return {};
  }
  return decode_grey_image(buffer.data(), size, why, bits, keep_16bit);
}

namespace {

/// later - earlier in seconds, for any two int64 times (the difference itself may not fit int64).
double seconds_between(TimeNs later, TimeNs earlier) {
  const bool forward = later >= earlier;
  const std::uint64_t d = forward ? static_cast<std::uint64_t>(later) - static_cast<std::uint64_t>(earlier)
                                  : static_cast<std::uint64_t>(earlier) - static_cast<std::uint64_t>(later);
  return (forward ? 1.0 : -1.0) * static_cast<double>(d) * 1e-9;
}

std::string imu_location(const std::string& where, const std::vector<int>& lines, std::size_t i, TimeNs t) {
  if (!where.empty() && i < lines.size()) return fmt::format("{}:{}", where, lines[i]);
  if (!where.empty()) return fmt::format("{} (t = {} s)", where, format_seconds(t));
  return fmt::format("IMU sample at t = {} s", format_seconds(t));
}

}  // namespace

IndexedSource::IndexedSource(std::vector<ImuSample> imu, std::vector<int> imu_lines, std::string imu_where,
                             std::vector<ImageEntry> images, std::vector<cv::Size> image_sizes,
                             const StreamCheckOptions& options)
    : reporter_(options.policy, stats_), image_sizes_(std::move(image_sizes)) {
  // IMU: finite values, strictly increasing time, no long dropouts.
  double period_s = options.imu_rate_hz > 0 ? 1.0 / options.imu_rate_hz : 0.0;
  if (period_s == 0.0 && imu.size() > 2) {
    std::vector<double> dts;
    for (std::size_t i = 1; i < imu.size(); ++i) dts.push_back(seconds_between(imu[i].t, imu[i - 1].t));
    std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2), dts.end());
    period_s = std::max(dts[dts.size() / 2], 1e-9);
  }
  imu_.reserve(imu.size());
  for (std::size_t i = 0; i < imu.size(); ++i) {
    const ImuSample& s = imu[i];
    if (!s.gyro.allFinite() || !s.accel.allFinite()) {
      reporter_.report(&SourceStats::non_finite,
                       fmt::format("{}: non-finite IMU value at t = {} s", imu_location(imu_where, imu_lines, i, s.t),
                                   format_seconds(s.t)));
      continue;
    }
    if (const std::string beyond = imu_range_problem(s, options.imu_range); !beyond.empty()) {
      reporter_.report(&SourceStats::imu_saturated,
                       fmt::format("{}: {}", imu_location(imu_where, imu_lines, i, s.t), beyond));
      continue;
    }
    if (!imu_.empty()) {
      const TimeNs prev = imu_.back().t;
      if (s.t == prev) {
        reporter_.report(&SourceStats::duplicate_timestamps,
                         fmt::format("{}: duplicate IMU timestamp {} s", imu_location(imu_where, imu_lines, i, s.t),
                                     format_seconds(s.t)));
        continue;
      }
      if (s.t < prev) {
        reporter_.report(&SourceStats::backwards_timestamps,
                         fmt::format("{}: IMU timestamp {} s goes backwards (previous {} s)",
                                     imu_location(imu_where, imu_lines, i, s.t), format_seconds(s.t),
                                     format_seconds(prev)));
        continue;
      }
      if (period_s > 0) {
        const double gap_s = seconds_between(s.t, prev);
        const double missing = std::round(gap_s / period_s) - 1.0;
        if (missing > options.max_imu_dropout) {
          reporter_.report(&SourceStats::imu_gaps,
                           fmt::format("{}: IMU gap of {:.3f} s before t = {} s (~{:.0f} samples missing, more than {})",
                                       imu_location(imu_where, imu_lines, i, s.t), gap_s, format_seconds(s.t),
                                       missing, options.max_imu_dropout));
          // Nothing to drop for a gap: the sample after it is kept.
        }
      }
    }
    imu_.push_back(s);
  }

  // Images: per camera strictly increasing time, files present.
  std::vector<TimeNs> last_t;
  std::vector<bool> seen_camera;
  images_.reserve(images.size());
  for (auto& e : images) {
    if (e.camera < 0) throw InvariantError(fmt::format("{}: negative camera index", e.listed_at));
    const auto c = static_cast<std::size_t>(e.camera);
    if (c >= last_t.size()) {
      last_t.resize(c + 1, 0);
      seen_camera.resize(c + 1, false);
    }
    TimeNs& prev = last_t[c];
    const bool seen = seen_camera[c];
    if (seen && e.t == prev) {
      reporter_.report(&SourceStats::duplicate_timestamps,
                       fmt::format("{}: duplicate image timestamp {} s", e.listed_at, format_seconds(e.t)));
      continue;
    }
    if (seen && e.t < prev) {
      reporter_.report(&SourceStats::backwards_timestamps,
                       fmt::format("{}: image timestamp {} s goes backwards (previous {} s)", e.listed_at,
                                   format_seconds(e.t), format_seconds(prev)));
      continue;
    }
    if (seen && seconds_between(e.t, prev) > kMaxImageJumpS) {
      reporter_.report(&SourceStats::timestamp_jumps,
                       fmt::format("{}: image timestamp {} s is {:.6g} s after the previous one of camera {} ({} s): a "
                                   "corrupt timestamp (this one or the previous)", e.listed_at, format_seconds(e.t),
                                   seconds_between(e.t, prev), e.camera, format_seconds(prev)));
      continue;
    }
    // error_code forms: a listed name the file system refuses (too long, ...) is a missing image, not an exception.
    std::error_code fs_error;
    if (options.check_files && !fs::is_regular_file(e.path, fs_error)) {
      reporter_.report(&SourceStats::missing_images, fmt::format("{}: image file {} not found", e.listed_at, e.path),
                       true);
      continue;
    }
    prev = e.t;
    seen_camera[c] = true;
    images_.push_back(std::move(e));
  }

  // Merge: by time, IMU before images at equal times, then by camera.
  order_.reserve(imu_.size() + images_.size());
  for (std::size_t i = 0; i < imu_.size(); ++i) order_.push_back({imu_[i].t, 0, i});
  for (std::size_t i = 0; i < images_.size(); ++i) order_.push_back({images_[i].t, 1 + images_[i].camera, i});
  std::stable_sort(order_.begin(), order_.end(),
                   [](const Item& a, const Item& b) { return a.t != b.t ? a.t < b.t : a.kind < b.kind; });
}

std::optional<Measurement> IndexedSource::next() {
  while (pos_ < order_.size()) {
    const Item item = order_[pos_++];
    if (item.kind == 0) {
      ++stats_.imu_samples;
      return imu_[item.index];
    }
    ImageEntry& e = images_[item.index];
    ImageFrame frame;
    frame.t = e.t;
    frame.camera = e.camera;
    frame.path = e.path;
    std::string why;
    frame.image = decode_ahead_ ? decode_ahead_->take(decode_index_[item.index], &why)
                                : read_grey_image(e.path, &why, &image_bits_);
    // Decoded ahead, a 16-bit image is scaled here, in stream order: by the depth of the images before it.
    if (frame.image.depth() == CV_16U) frame.image = to_grey8(frame.image, &why, &image_bits_);
    if (frame.image.empty()) {
      std::error_code fs_error;
      const bool missing = !fs::exists(e.path, fs_error);
      const bool unsupported = !missing && why.rfind("unsupported", 0) == 0;
      reporter_.report(missing       ? &SourceStats::missing_images
                       : unsupported ? &SourceStats::unsupported_images
                                     : &SourceStats::undecodable_images,
                       fmt::format("{}: image {} {}", e.listed_at, e.path, missing ? "not found" : why), true);
      continue;
    }
    const auto c = static_cast<std::size_t>(e.camera);
    const bool checked = c < image_sizes_.size() && image_sizes_[c].width > 0 && image_sizes_[c].height > 0;
    if (checked && frame.image.size() != image_sizes_[c]) {
      reporter_.report(&SourceStats::wrong_size_images,
                       fmt::format("{}: image {} is {}x{}, the calibration of camera {} says {}x{}", e.listed_at,
                                   e.path, frame.image.cols, frame.image.rows, e.camera, image_sizes_[c].width,
                                   image_sizes_[c].height));
      continue;
    }
    ++stats_.images;
    return frame;
  }
  return std::nullopt;
}

IndexedSource::~IndexedSource() = default;

bool IndexedSource::prefetch(const PrefetchOptions& options) {
  if (options.threads <= 0) return false;
  // The images still to come, in stream order (cameras interleaved by time).
  std::vector<std::string> paths;
  decode_index_.assign(images_.size(), 0);
  for (std::size_t p = pos_; p < order_.size(); ++p) {
    if (order_[p].kind == 0) continue;
    decode_index_[order_[p].index] = paths.size();
    paths.push_back(images_[order_[p].index].path);
  }
  decode_ahead_.reset();  // a second call restarts the workers
  decode_ahead_ = std::make_unique<DecodeAhead>(std::move(paths), options.threads, options.depth);
  return true;
}

bool IndexedSource::seek(TimeNs t) {
  while (pos_ < order_.size() && order_[pos_].t < t) ++pos_;
  return true;
}

WindowSource::WindowSource(std::unique_ptr<Source> inner, double start_offset_s, double duration_s)
    : inner_(std::move(inner)), start_offset_s_(start_offset_s), duration_s_(duration_s) {
  if (!inner_) throw ConfigError("a window of a stream needs a stream");
  if (!(start_offset_s >= 0.0) || !std::isfinite(start_offset_s) || !std::isfinite(duration_s)) {
    throw ConfigError(fmt::format("stream window: start offset {} s must be finite and >= 0, duration {} s finite",
                                  start_offset_s, duration_s));
  }
}

std::optional<std::size_t> WindowSource::image_count() const {
  // Unknown inside the window, except when the window is the whole stream.
  if (start_offset_s_ == 0.0 && duration_s_ <= 0.0) return inner_->image_count();
  return std::nullopt;
}

std::optional<Measurement> WindowSource::next() {
  if (!started_) {
    started_ = true;
    auto m = inner_->next();
    if (!m) return std::nullopt;
    const TimeNs t_first = time_of(*m);
    // Saturating: a window that reaches past the int64 time range ends (or starts) at its end.
    constexpr TimeNs kEnd = std::numeric_limits<TimeNs>::max();
    const auto offset = from_seconds_checked(start_offset_s_);
    const auto start = offset ? add_checked(t_first, *offset) : std::nullopt;
    if (!start) return std::nullopt;  // the window starts after any representable time: it is empty
    const TimeNs t_start = *start;
    const auto length = from_seconds_checked(duration_s_);
    end_ = duration_s_ > 0.0 ? (length ? add_checked(t_start, *length).value_or(kEnd) : kEnd) : kEnd;
    if (time_of(*m) < t_start) {
      if (!inner_->seek(t_start)) {
        do {
          m = inner_->next();
        } while (m && time_of(*m) < t_start);
      } else {
        m = inner_->next();
      }
    }
    if (!m || time_of(*m) > end_) return std::nullopt;
    return m;
  }
  auto m = inner_->next();
  if (!m || time_of(*m) > end_) return std::nullopt;
  return m;
}

VideoSource::VideoSource(const std::string& path, double rate_hz, TimeNs t0, cv::Size expected_size,
                         BadInputPolicy policy, const Options& options)
    : path_(path),
      rate_hz_(rate_hz),
      t0_(t0),
      expected_size_(expected_size),
      reporter_(policy, stats_),
      judge_end_(options.judge_end) {
  if (options.continue_from != nullptr) stats_.add_problems(*options.continue_from);
  std::error_code fs_error;
  if (!fs::is_regular_file(path, fs_error)) throw IoError(fmt::format("{}: file not found", path));
  {
    // OpenCV logs every backend it tries on a file it cannot open (a dozen lines of GStreamer, FFmpeg and image
    // sequence errors): quiet while opening, our one line says what failed. FFmpeg first, the backend for files
    // (its own messages, "moov atom not found", follow OPENCV_FFMPEG_LOGLEVEL, which the rtslam CLI sets at start).
    codecs::load_plugin();  // a missing plugin throws here, before the level is changed
    const cv::utils::logging::LogLevel level = cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
    capture_ = codecs::open_video(path, cv::CAP_FFMPEG);
    if (!capture_) capture_ = codecs::open_video(path, cv::CAP_ANY);
    cv::utils::logging::setLogLevel(level);
  }
  if (!capture_) throw IoError(fmt::format("{}: cannot open the video (unknown format or codec)", path));
  const double fps = capture_->get(cv::CAP_PROP_FPS);
  const double n = capture_->get(cv::CAP_PROP_FRAME_COUNT);
  if (n > 0 && std::isfinite(n)) frame_count_ = static_cast<std::size_t>(n);
  // OpenCV's count is the container's (MP4, AVI: then its frame rate is the mean one) or its duration x its frame
  // rate (Matroska, WebM): either way count / rate is about the duration.
  if (frame_count_ && fps > 0 && std::isfinite(fps)) duration_s_ = static_cast<double>(*frame_count_) / fps;
  // How the container times its frames, from the first ones (kept, converted, for next()): presentation times when
  // the backend gives them (the first at 0, the others after it), else the container's frame rate. A given rate
  // times the frames at i / rate whatever the container says (its times still tell a truncated file).
  constexpr std::size_t kProbeFrames = 5;
  has_pts_ = true;  // decode_frame takes the times
  Frame f;
  while (head_.size() < kProbeFrames && decode_frame(f)) head_.push_back(std::move(f));
  std::vector<double> intervals;
  double first_ms = 0.0, last_ms = 0.0;
  std::size_t timed = 0;  // probed frames with a time (the first, and the later ones with a positive time)
  bool any_time = false;  // a frame with a finite time other than 0
  for (std::size_t k = 0; k < head_.size(); ++k) {
    const double t = head_[k].pts_ms;
    if (std::isfinite(t) && t != 0.0) any_time = true;
    if (!std::isfinite(t) || (k > 0 && !(t > 0))) continue;
    if (timed > 0 && t > last_ms) intervals.push_back(t - last_ms);
    if (timed == 0) first_ms = t;
    last_ms = std::max(last_ms, t);
    ++timed;
  }
  const bool no_times = head_.size() >= 2 && !any_time;  // (the backend gives every frame time 0)
  has_pts_ = !no_times && !head_.empty();
  use_pts_ = has_pts_ && !(rate_hz_ > 0);
  // The lower median interval's rate (with a few frames dropped, the camera's), and the mean one (a constant rate in a
  // container of millisecond times: intervals of 33 and 34 ms at 30 Hz).
  double median_hz = 0.0, mean_hz = 0.0;
  if (has_pts_ && !intervals.empty()) {
    const auto mid = intervals.begin() + static_cast<std::ptrdiff_t>((intervals.size() - 1) / 2);
    std::nth_element(intervals.begin(), mid, intervals.end());
    median_hz = 1e3 / *mid;
    mean_hz = 1e3 * static_cast<double>(intervals.size()) / (last_ms - first_ms);
    // A rate many times the frames' own is one guessed from the time base (Matroska: 1000 "fps"), and the count made
    // from it no count: the duration at the frames' own rate instead (the progress line's total).
    if (duration_s_ > 0 && fps > 4.0 * median_hz) {
      frame_count_ = static_cast<std::size_t>(std::llround(duration_s_ * median_hz));
    }
  }
  const bool container_rate = mean_hz > 0 && std::abs(fps - mean_hz) <= 0.01 * mean_hz;
  file_hz_ = container_rate || !(median_hz > 0) ? fps : median_hz;
  if (!(rate_hz_ > 0)) rate_hz_ = file_hz_;
  if (!(rate_hz_ > 0) || !std::isfinite(rate_hz_)) {
    throw ConfigError(fmt::format("{}: the video does not state its frame rate: give the rate option", path));
  }
}

VideoSource::~VideoSource() = default;

bool VideoSource::read_frame(Frame& f) {
  if (!head_.empty()) {
    f = std::move(head_.front());
    head_.pop_front();
    return true;
  }
  return decode_frame(f);
}

bool VideoSource::decode_frame(Frame& f) {
  cv::Mat raw;
  if (!capture_->read(raw) || raw.empty()) return false;
  f.pts_ms = has_pts_ ? capture_->get(cv::CAP_PROP_POS_MSEC) : 0.0;
  f.why.clear();
  f.grey = to_grey8(raw, &f.why, &image_bits_);  // in stream order (a 16-bit stream's depth so far)
  return true;
}

void VideoSource::report_early_end() {
  if (end_reported_ || !judge_end_) return;
  // The container says how many frames (or seconds) it holds: ending well before is a truncated or corrupt file, not
  // its end. Slack for counts that are estimates (MKV/WebM: duration x fps, audio included; variable frame rates): 5
  // frames or 2 %.
  if (has_pts_) {
    if (duration_s_ <= 0 || !last_pts_ms_) return;
    const double end_s = *last_pts_ms_ * 1e-3;
    // (Slack in the file's own frames: a given rate only re-times them.)
    const double frame_s = file_hz_ > 0 && std::isfinite(file_hz_) ? 1.0 / file_hz_ : 0.0;
    if (end_s + std::max(5.0 * frame_s, 0.02 * duration_s_) >= duration_s_) return;
    end_reported_ = true;
    reporter_.report(&SourceStats::undecodable_images,
                     fmt::format("{}: the video ends at frame {} ({:.3f} s) of the {:.3f} s its container lists "
                                 "(truncated or corrupt)", path_, index_, end_s, duration_s_),
                     true);
    return;
  }
  const std::size_t slack = frame_count_ ? std::max<std::size_t>(5, *frame_count_ / 50) : 0;
  if (frame_count_ && index_ + slack < *frame_count_) {
    end_reported_ = true;
    reporter_.report(&SourceStats::undecodable_images,
                     fmt::format("{}: the video ends at frame {} of the {} its container lists (truncated or "
                                 "corrupt)", path_, index_, *frame_count_),
                     true);
  }
}

std::optional<Measurement> VideoSource::next() {
  while (true) {
    Frame f;
    if (!read_frame(f)) {
      report_early_end();
      return std::nullopt;
    }
    double pts_ms = f.pts_ms;
    // No time (OpenCV 4.6: the frames its decoder held at the end of the file): one nominal interval after the last.
    if (has_pts_ && last_pts_ms_ && (!std::isfinite(pts_ms) || (pts_ms == 0.0 && *last_pts_ms_ > 0.0))) {
      pts_ms = *last_pts_ms_ + 1e3 / (file_hz_ > 0 && std::isfinite(file_hz_) ? file_hz_ : rate_hz_);
    }
    const std::size_t i = index_++;
    ImageFrame frame;
    frame.path = fmt::format("{}#{}", path_, i);
    std::optional<TimeNs> t;
    if (use_pts_) {
      if (last_pts_ms_ && pts_ms == *last_pts_ms_) {
        reporter_.report(&SourceStats::duplicate_timestamps,
                         fmt::format("{}: duplicate presentation time {:.3f} ms (give the rate option to time the "
                                     "frames at i / rate)", frame.path, pts_ms));
        continue;
      }
      if (last_pts_ms_ && !(pts_ms > *last_pts_ms_)) {
        reporter_.report(&SourceStats::backwards_timestamps,
                         fmt::format("{}: presentation time {:.3f} ms goes backwards (previous {:.3f} ms; give the "
                                     "rate option to time the frames at i / rate)", frame.path, pts_ms,
                                     *last_pts_ms_));
        continue;
      }
      t = from_seconds_checked(pts_ms * 1e-3);
    } else {
      t = from_seconds_checked(static_cast<double>(i) / rate_hz_);
    }
    const auto t_frame = t ? add_checked(t0_, *t) : std::nullopt;
    if (!t_frame) {
      throw DataError(use_pts_ ? fmt::format("{}: presentation time {:g} ms lies beyond the int64 nanosecond time "
                                             "range", frame.path, pts_ms)
                               : fmt::format("{}: frame {} at {:g} Hz lies beyond the int64 nanosecond time range",
                                             path_, i, rate_hz_));
    }
    frame.t = *t_frame;
    if (has_pts_) last_pts_ms_ = pts_ms;
    frame.image = std::move(f.grey);
    if (frame.image.empty()) {
      reporter_.report(&SourceStats::unsupported_images, fmt::format("{}: frame {}", frame.path, f.why), true);
      continue;
    }
    if (expected_size_.width > 0 && expected_size_.height > 0 && frame.image.size() != expected_size_) {
      reporter_.report(&SourceStats::wrong_size_images,
                       fmt::format("{}: frame is {}x{}, the calibration says {}x{}", frame.path, frame.image.cols,
                                   frame.image.rows, expected_size_.width, expected_size_.height));
      continue;
    }
    ++stats_.images;
    return frame;
  }
}

}  // namespace rtslam::io
