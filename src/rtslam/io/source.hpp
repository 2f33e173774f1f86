#pragma once
// The measurement stream: every input (dataset reader, video, simulator) becomes one time-ordered sequence of
// measurements. At equal timestamps IMU samples come before odometry readings, those before images, and images by
// camera index; the simulator's absolute fixes (PositionSample, PoseSample) come after the images of their time.
//
// Bad input (timestamps that go backwards, duplicates, IMU dropouts, NaNs, malformed lines, missing or undecodable
// images) is reported with the file and line or timestamp. The policy chooses between stopping with an error
// (default: DataError for bad values, IoError for bad files) and skipping the offending item, counted in
// SourceStats. Nothing is dropped silently: every skip is counted and its message kept (the first 100) and logged.
#include <cstddef>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json_fwd.hpp>
#include <opencv2/core.hpp>

#include "rtslam/core/time.hpp"
#include "rtslam/io/codecs.hpp"

namespace rtslam::io {

/// One IMU reading in the IMU frame: angular rate [rad/s] and specific force [m/s^2].
struct ImuSample {
  TimeNs t = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
};

/// One camera image, decoded when the stream reaches it.
struct ImageFrame {
  TimeNs t = 0;
  int camera = 0;     // index into Rig::cameras
  cv::Mat image;      // CV_8UC1
  std::string path;   // file it came from ("video.mp4#123" for video frames)
};

/// One wheel-odometry reading: the robot's pose increment from the previous reading (t_from) to this one (t), in the
/// robot frame at t_from: dp the displacement (m), dtheta the rotation vector (rad). From the simulator
/// (sim/odometry.hpp); the dataset readers give none.
struct OdometrySample {
  TimeNs t = 0;
  TimeNs t_from = 0;
  Eigen::Vector3d dp = Eigen::Vector3d::Zero();
  Eigen::Vector3d dtheta = Eigen::Vector3d::Zero();
};

/// One absolute position fix (GPS-like): the antenna position in the sensor's world frame (m).
struct PositionSample {
  TimeNs t = 0;
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
};

/// One absolute pose (motion capture): the marker body's pose T_GM in the sensor's world frame.
struct PoseSample {
  TimeNs t = 0;
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
};

using Measurement = std::variant<ImuSample, ImageFrame, OdometrySample, PositionSample, PoseSample>;

/// The range of an IMU's readings, per axis. A reading beyond it is saturated or corrupt: its true value is unknown,
/// so it must never reach the integrator as if it were measured. Without a calibrated full scale the range is the
/// plausibility limit of any IMU a SLAM rig carries (the widest MEMS parts: ±4000 deg/s = 70 rad/s, ±400 g), with
/// margin: a reading beyond it is a corrupt value, not a motion.
struct ImuRange {
  static constexpr double kMaxPlausibleGyro = 200.0;     // rad/s (11,500 deg/s)
  static constexpr double kMaxPlausibleAccel = 10000.0;  // m/s² (1020 g)
  double gyro_rad_s = kMaxPlausibleGyro;                 // |ω| per axis
  double accel_m_s2 = kMaxPlausibleAccel;                // |a| per axis
  /// The full scales of a calibration (sensor.yaml gyroscope_saturation / accelerometer_saturation, or the config
  /// keys imu/gyro_saturation / imu/accel_saturation), each capped by the plausibility limit; absent ones keep it.
  static ImuRange from_full_scale(std::optional<double> gyro_saturation, std::optional<double> accel_saturation);
};

/// Empty when every axis of the sample lies within the range (a reading exactly at the full scale is within it: a
/// saturated sensor reports its full scale); else what lies beyond, e.g. "accelerometer a_y = 1e+30 m/s² is beyond
/// the sensor's range ±160 m/s² (saturated or corrupt)". Non-finite readings are beyond any range.
std::string imu_range_problem(const ImuSample& s, const ImuRange& range);

/// The timestamp of a measurement.
TimeNs time_of(const Measurement& m);

enum class BadInputPolicy { Error, Skip };

/// Decoding ahead of the consumer (Source::prefetch): `threads` worker threads decode the next images of the stream
/// while the consumer processes earlier ones; at most `depth` images are decoded ahead (0: 4 per thread), so the
/// memory held is about (depth + threads) decoded images plus one encoded file per thread (752x480 grey: 0.36 MB
/// an image; 2 threads, depth 8: under 4 MB). The stream itself does not change (same measurements, same order,
/// same errors at the same point).
struct PrefetchOptions {
  int threads = 0;        // 0: off
  std::size_t depth = 0;  // images decoded ahead at most (0: 4 * threads)
};

/// The default number of decoding threads for `hardware_threads` (0: unknown): one per hardware thread but the
/// filter's, at most 4; 0 (off) on one core, where a decoding thread could only take time from the filter. On 2 cores
/// one decoding thread beats two (26 Nov, hd1, three runs each: 652-664 against 541-553 images/s, per-frame p99
/// 2.06-2.14 against 2.34-2.85 ms): a second one only preempts the filter thread.
int default_prefetch_threads(unsigned hardware_threads);
/// default_prefetch_threads for this machine (std::thread::hardware_concurrency()).
int default_prefetch_threads();

/// Parses "error" / "skip" (ConfigError naming `where` otherwise).
BadInputPolicy bad_input_policy_from_string(const std::string& s, const std::string& where = "bad_input");

/// What a source yielded and what it skipped (with the Skip policy) or noticed.
struct SourceStats {
  std::size_t images = 0;       // image frames yielded
  std::size_t imu_samples = 0;  // IMU samples yielded
  // Problems, each counted once (with Skip, the offending item was dropped, except gaps: nothing to drop).
  std::size_t backwards_timestamps = 0;
  std::size_t duplicate_timestamps = 0;
  std::size_t imu_gaps = 0;  // dropouts longer than the allowed number of samples
  std::size_t non_finite = 0;
  std::size_t malformed_lines = 0;
  std::size_t missing_images = 0;
  std::size_t undecodable_images = 0;
  std::size_t wrong_size_images = 0;
  std::size_t imu_saturated = 0;  // IMU samples beyond the sensor's range (ImuRange): saturated or corrupt
  std::size_t unsupported_images = 0;  // images of a pixel type that cannot be converted to 8-bit grey faithfully
  // An image more than kMaxImageJumpS after the previous one of its camera; a live IMU stream's implausible time
  // (imu_stream.hpp).
  std::size_t timestamp_jumps = 0;
  // Not bad input: what a live source (live_source.hpp) dropped, good data it had no room or no use for: images and
  // IMU samples the filter fell too far behind to take (its queues full), camera frames that waited while no IMU
  // sample had come at all (an inertial filter cannot start on them).
  std::size_t live_dropped_images = 0;
  std::size_t live_dropped_imu_samples = 0;
  std::size_t live_images_before_imu = 0;
  std::vector<std::string> messages;  // the first kMaxMessages problem messages

  static constexpr std::size_t kMaxMessages = 100;
  std::size_t problems() const;
  /// Adds the problem counters, the live drops and the messages of `other` (e.g. problems met while parsing, before
  /// streaming).
  void add_problems(const SourceStats& other);
  /// One line, e.g. "95 images, 29120 IMU samples; skipped: 2 duplicate timestamps, 1 undecodable image".
  std::string summary() const;
  nlohmann::json to_json() const;
};

/// Counts a problem in `stats` under `counter` and applies the policy: throws (IoError when `file_problem`, else
/// DataError) with `message` under Error; logs a warning (the first 20, then debug) and records it under Skip.
class BadInputReporter {
 public:
  BadInputReporter(BadInputPolicy policy, SourceStats& stats) : policy_(policy), stats_(&stats) {}
  void report(std::size_t SourceStats::*counter, const std::string& message, bool file_problem = false);
  BadInputPolicy policy() const { return policy_; }

 private:
  BadInputPolicy policy_;
  SourceStats* stats_;
};

/// A time-ordered stream of measurements.
class Source {
 public:
  virtual ~Source() = default;
  /// The next measurement, or nullopt at the end. Throws under the Error policy when it meets bad input.
  virtual std::optional<Measurement> next() = 0;
  virtual const SourceStats& stats() const = 0;
  /// Number of images the stream will yield, when known (for progress and ETA).
  virtual std::optional<std::size_t> image_count() const { return std::nullopt; }
  /// Moves the stream to its first measurement at or after t without decoding what it passes; false when the
  /// source cannot (callers then read and drop).
  virtual bool seek(TimeNs /*t*/) { return false; }
  /// Starts decoding images ahead of next() in worker threads (PrefetchOptions); call before the first next().
  /// The stream is unchanged: the same measurements in the same order, bad input reported (or skipped) at the same
  /// point. False when the source cannot (it is then read as before); wrappers forward to their inner source.
  virtual bool prefetch(const PrefetchOptions& /*options*/) { return false; }
  /// Asks a next() that waits in another thread for data a live source paces (a stand-in file's next frame) to
  /// return the end of the stream now (wrappers may still hand out what they read before). Thread-safe. Sources that
  /// never wait ignore it, and so does a camera device (its grab waits at most one frame period).
  virtual void interrupt() {}
};

/// A window [first + start_offset, first + start_offset + duration] of another stream (`first`: the time of its
/// first measurement): what lies before is skipped (without decoding where the source can seek), the stream ends
/// after the window. duration <= 0: to the end. For starting a run anywhere in a recording.
class WindowSource final : public Source {
 public:
  WindowSource(std::unique_ptr<Source> inner, double start_offset_s, double duration_s);
  std::optional<Measurement> next() override;
  const SourceStats& stats() const override { return inner_->stats(); }
  std::optional<std::size_t> image_count() const override;
  bool prefetch(const PrefetchOptions& options) override { return inner_->prefetch(options); }
  void interrupt() override { inner_->interrupt(); }

 private:
  std::unique_ptr<Source> inner_;
  double start_offset_s_, duration_s_;
  bool started_ = false;
  TimeNs end_ = 0;
};

/// An image not yet decoded: time, camera, file and where it was listed (for messages).
struct ImageEntry {
  TimeNs t = 0;
  int camera = 0;
  std::string path;
  std::string listed_at;  // "cam0/data.csv:12", or the path itself
};

/// Options of the per-stream checks.
/// Two images of one camera further apart than this in one recording are a corrupt timestamp (a digit too many, a
/// sign), not a pause: no sensor stream of a SLAM run stops for an hour and resumes; split such a recording.
constexpr double kMaxImageJumpS = 3600.0;

struct StreamCheckOptions {
  BadInputPolicy policy = BadInputPolicy::Error;
  double imu_rate_hz = 0.0;    // nominal IMU rate; 0 = take the median interval
  int max_imu_dropout = 3;     // more missing samples than this in a row is a gap
  bool check_files = true;     // check at open time that every image file exists
  ImuRange imu_range;          // samples beyond it are bad input (counted as imu_saturated)
};

class DecodeAhead;  // prefetch.hpp

/// A stream built from in-memory IMU samples and a list of image files (decoded lazily). The constructor checks
/// each stream (order, duplicates, gaps, missing files) and merges them in time order. Every reader except video
/// builds one of these; the simulator can too.
class IndexedSource : public Source {
 public:
  /// `imu_lines[i]` / `imu_where` locate sample i for messages (may be empty). `image_sizes[c]` is the expected
  /// width/height of camera c (0x0 = unchecked).
  IndexedSource(std::vector<ImuSample> imu, std::vector<int> imu_lines, std::string imu_where,
                std::vector<ImageEntry> images, std::vector<cv::Size> image_sizes, const StreamCheckOptions& options);
  std::optional<Measurement> next() override;
  const SourceStats& stats() const override { return stats_; }
  std::optional<std::size_t> image_count() const override { return images_.size(); }
  bool seek(TimeNs t) override;
  /// Decodes the image files ahead in worker threads (the checks and the bad-input policy stay in next()).
  bool prefetch(const PrefetchOptions& options) override;
  ~IndexedSource() override;
  /// Merges problems a reader met while parsing its lists (they count in stats()).
  void add_parse_problems(const SourceStats& parse_stats) { stats_.add_problems(parse_stats); }

 private:
  struct Item {
    TimeNs t;
    int kind;  // 0 = IMU, 1 + camera = image
    std::size_t index;
  };
  SourceStats stats_;
  BadInputReporter reporter_;
  std::vector<ImuSample> imu_;
  std::vector<ImageEntry> images_;
  std::vector<cv::Size> image_sizes_;
  std::vector<Item> order_;
  std::size_t pos_ = 0;
  int image_bits_ = 8;  // significant bits of the 16-bit images seen so far (to_grey8)
  std::unique_ptr<DecodeAhead> decode_ahead_;  // prefetch.hpp; null without prefetch
  std::vector<std::size_t> decode_index_;      // with prefetch: images_[i] is decode_ahead_'s image decode_index_[i]
};

/// A video file read through OpenCV (FFmpeg first), its frames converted to grey. Frame times: t0 + the container's
/// presentation time of each frame (variable frame rates, as phones record, keep their real times), strictly
/// increasing (a duplicate or backward time is bad input); or t0 + i / rate_hz when rate_hz > 0 is given, or when
/// the backend gives no presentation times (every frame at 0) — then at the container's frame rate. OpenCV 4.6 gives
/// no time (0) for the frames its decoder still held at the end of the file (H.264 with B-frames): each of those is
/// placed one nominal interval after the one before. rate_hz() is the nominal rate: the given one; else the
/// container's when the first frames' mean interval agrees with it within 1 %; else one over their lower median
/// interval. A file that ends well before the duration its container states is reported as truncated (judge_end).
class VideoSource : public Source {
 public:
  struct Options {
    /// Report a file that ends well before its container's duration (off for a file played in a loop: its end only
    /// starts the next pass).
    bool judge_end = true;
    /// Problems met before (earlier passes over the same file): counted on from, and warned about within the same
    /// budget of warnings.
    const SourceStats* continue_from = nullptr;
  };
  VideoSource(const std::string& path, double rate_hz, TimeNs t0, cv::Size expected_size, BadInputPolicy policy)
      : VideoSource(path, rate_hz, t0, expected_size, policy, Options{}) {}
  VideoSource(const std::string& path, double rate_hz, TimeNs t0, cv::Size expected_size, BadInputPolicy policy,
              const Options& options);
  ~VideoSource() override;
  std::optional<Measurement> next() override;
  const SourceStats& stats() const override { return stats_; }
  std::optional<std::size_t> image_count() const override { return frame_count_; }
  double rate_hz() const { return rate_hz_; }

 private:
  struct Frame {
    cv::Mat grey;     // to_grey8's (empty: refused, why says why)
    std::string why;
    double pts_ms = 0.0;
  };
  /// The next frame (the probed ones first), converted, and its presentation time (meaningful when has_pts_); false
  /// at the end.
  bool read_frame(Frame& f);
  /// The next frame from the file (decode_frame: what read_frame does without the probed frames).
  bool decode_frame(Frame& f);
  void report_early_end();

  std::string path_;
  double rate_hz_ = 0.0;
  double file_hz_ = 0.0;  // the file's own nominal rate (rate_hz_ unless a rate was given)
  TimeNs t0_ = 0;
  cv::Size expected_size_;
  SourceStats stats_;
  BadInputReporter reporter_;
  std::unique_ptr<codecs::VideoReader> capture_;
  std::size_t index_ = 0;
  int image_bits_ = 8;
  std::optional<std::size_t> frame_count_;
  double duration_s_ = 0.0;  // the container's (frame count / frame rate), 0 when unknown
  bool end_reported_ = false;
  bool judge_end_ = true;
  bool has_pts_ = false;                         // the backend gives presentation times
  bool use_pts_ = false;                         // and the frames are timed by them (no rate given)
  std::deque<Frame> head_;                       // frames read ahead at opening (to see how they are timed)
  std::optional<double> last_pts_ms_;            // presentation time of the last frame returned
};

/// Converts a decoded image to 8-bit grey (CV_8UC1). Channels: 1 (grey), 2 (grey + alpha: the grey), 3 (BGR) and 4
/// (BGRA), colour with OpenCV's weights. Depth: 8-bit as is; 16-bit by its significant bits — the smallest of 8, 10,
/// 12, 14 or 16 bits that holds the largest value, and at least `*bits` (the stream's depth so far, so that a dark
/// frame of a 12-bit camera is not brightened) — shifted down to 8 (a 16-bit file holding 8-bit values keeps them;
/// `*bits` is updated). Float and signed pixels are refused: an empty Mat, `why` says why ("unsupported: ...").
cv::Mat to_grey8(const cv::Mat& image, std::string* why = nullptr, int* bits = nullptr);

/// Decodes an encoded image to 8-bit grey with OpenCV's imdecode at its own depth, then to_grey8. Only the formats
/// the readers accept are decoded — PNG, PNM (PBM/PGM/PPM), JPEG, BMP, TIFF — and only up to the size limits of
/// image_header.hpp, checked on the header before anything is allocated. Returns an empty Mat if the bytes are not
/// such an image, cannot be decoded or hold pixels to_grey8 refuses; `why` (if given) then says which ("cannot be
/// decoded: ..." or "unsupported: ..."). This is the decode path of every image reader (read_grey_image). 8-bit grey
/// PNGs take a faster path with the same pixels (png_grey.hpp). `keep_16bit`: a 16-bit image comes back as 16-bit
/// grey (CV_16UC1), not yet scaled — for decoders running ahead of the stream, whose consumer scales it with to_grey8
/// in stream order, since the scale depends on the depth of the images before it (`bits`). Images other than 8-bit
/// grey PNGs are decoded by OpenCV through the codecs plugin (codecs.hpp): IoError when it cannot be loaded (a
/// setup error, not a bad image).
cv::Mat decode_grey_image(const unsigned char* data, std::size_t size, std::string* why = nullptr,
                          int* bits = nullptr, bool keep_16bit = false);

/// Reads an image file and decodes it with decode_grey_image; an empty Mat if it is missing or cannot be decoded
/// (`why` says which); IoError as decode_grey_image.
cv::Mat read_grey_image(const std::string& path, std::string* why = nullptr, int* bits = nullptr,
                        bool keep_16bit = false);

}  // namespace rtslam::io
