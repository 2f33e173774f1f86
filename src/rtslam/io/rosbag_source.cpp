// Reading and writing ROS1 bags (rosbag_source.hpp). The only translation unit of io that includes ROS headers:
// compiled as C++17 (Noetic's generated messages do not compile as C++20, cmake/RtslamRos.cmake) and only in
// builds with ROS; rosbag_unavailable.cpp stands in for it otherwise.
#include "rtslam/io/rosbag_source.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>

#include <fmt/format.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/io/text.hpp"
#include "rtslam/io/trajectory_io.hpp"

namespace rtslam::io {
namespace fs = std::filesystem;

bool rosbag_supported() { return true; }

namespace {

constexpr const char* kImageType = "sensor_msgs/Image";
constexpr const char* kCompressedType = "sensor_msgs/CompressedImage";
constexpr const char* kImuType = "sensor_msgs/Imu";

TimeNs to_ns(const ros::Time& t) { return static_cast<TimeNs>(t.sec) * kNsPerSecond + static_cast<TimeNs>(t.nsec); }

ros::Time to_ros_time(TimeNs t) {
  return ros::Time(static_cast<std::uint32_t>(t / kNsPerSecond), static_cast<std::uint32_t>(t % kNsPerSecond));
}

/// What to read from a bag, and how to check it.
struct BagReadSpec {
  std::vector<std::string> image_topics;  // camera i
  std::string imu_topic;                  // empty: none
  bool receive_time = false;
  StreamCheckOptions checks;
  std::vector<cv::Size> image_sizes;  // camera i, 0x0: unchecked
};

/// A bag as a time-ordered stream: indexed and checked when it is constructed, images decoded by next().
class RosbagSource final : public Source {
 public:
  RosbagSource(const std::string& path, const BagReadSpec& spec);
  std::optional<Measurement> next() override;
  const SourceStats& stats() const override { return stats_; }
  std::optional<std::size_t> image_count() const override { return images_.size(); }

 private:
  struct ImageItem {
    TimeNs t;
    int camera;
    std::size_t k;        // message index on its topic (0-based)
    std::size_t message;  // into messages_
    bool compressed;
  };
  struct Item {
    TimeNs t;
    int kind;  // 0 = IMU, 1 + camera = image
    std::size_t index;
  };
  /// "FILE.bag /cam0/image_raw message 12 (t = 1.000000000 s)", message numbers 1-based.
  std::string where(const std::string& topic, std::size_t k, TimeNs t) const;
  void index(const BagReadSpec& spec);
  cv::Mat decode(const ImageItem& item, std::string* error) const;

  std::string path_;
  std::vector<std::string> image_topics_;
  std::vector<cv::Size> image_sizes_;
  std::unique_ptr<rosbag::Bag> bag_;
  SourceStats stats_;
  BadInputReporter reporter_;
  std::vector<ImuSample> imu_;
  std::vector<rosbag::MessageInstance> messages_;  // the images' messages (they point into bag_)
  std::vector<ImageItem> images_;
  std::vector<Item> order_;
  std::size_t pos_ = 0;
  int image_bits_ = 8;  // significant bits of the 16-bit compressed images so far (to_grey8, in stream order)
};

std::string zero_stamp_hint(TimeNs t, bool receive_time) {
  return t == 0 && !receive_time ? " (header stamp 0: the messages were not stamped; use the bag's receive times, "
                                   "option bag_receive_time)"
                                 : "";
}

RosbagSource::RosbagSource(const std::string& path, const BagReadSpec& spec)
    : path_(path),
      image_topics_(spec.image_topics),
      image_sizes_(spec.image_sizes),
      bag_(std::make_unique<rosbag::Bag>()),
      reporter_(spec.checks.policy, stats_) {
  try {
    bag_->open(path, rosbag::bagmode::Read);
    index(spec);
  } catch (const rosbag::BagException& e) {
    throw IoError(fmt::format("{}: cannot be read as a ROS bag: {}", path, e.what()));
  }
}

std::string RosbagSource::where(const std::string& topic, std::size_t k, TimeNs t) const {
  return fmt::format("{} {} message {} (t = {} s)", path_, topic, k + 1, format_seconds(t));
}

void RosbagSource::index(const BagReadSpec& spec) {
  // The bag's topics, for checks and messages.
  std::map<std::string, std::string> types;
  std::map<std::string, std::size_t> counts;
  {
    rosbag::View all(*bag_);
    for (const rosbag::ConnectionInfo* c : all.getConnections()) types[c->topic] = c->datatype;
  }
  for (const auto& [topic, type] : types) counts[topic] = rosbag::View(*bag_, rosbag::TopicQuery(topic)).size();
  const auto topic_list = [&] {
    std::string s;
    for (const auto& [topic, type] : types) {
      s += fmt::format("{}{} ({}, {} messages)", s.empty() ? "" : ", ", topic, type, counts[topic]);
    }
    return s.empty() ? std::string("no topic") : s;
  };
  std::map<std::string, int> camera_of_topic;
  std::vector<bool> compressed(spec.image_topics.size(), false);
  for (std::size_t c = 0; c < spec.image_topics.size(); ++c) {
    const std::string& topic = spec.image_topics[c];
    const auto it = types.find(topic);
    if (it == types.end()) {
      throw IoError(fmt::format("{}: no image topic '{}' (camera {}); the bag has {}: set the image_topics option",
                                path_, topic, c, topic_list()));
    }
    if (it->second != kImageType && it->second != kCompressedType) {
      throw ConfigError(
          fmt::format("{}: topic '{}' is {}, not {} or {}", path_, topic, it->second, kImageType, kCompressedType));
    }
    if (!camera_of_topic.emplace(topic, static_cast<int>(c)).second) {
      throw ConfigError(fmt::format("{}: topic '{}' is given for two cameras", path_, topic));
    }
    compressed[c] = it->second == kCompressedType;
  }
  std::string imu_topic = spec.imu_topic;
  if (!imu_topic.empty()) {
    const auto it = types.find(imu_topic);
    if (it == types.end()) {
      logger("io")->warn("{}: no IMU topic '{}' (the bag has {}): streaming images only", path_, imu_topic,
                         topic_list());
      imu_topic.clear();
    } else if (it->second != kImuType) {
      throw ConfigError(fmt::format("{}: topic '{}' is {}, not {}", path_, imu_topic, it->second, kImuType));
    } else if (camera_of_topic.count(imu_topic) != 0) {
      throw ConfigError(fmt::format("{}: topic '{}' is given for a camera and the IMU", path_, imu_topic));
    }
  }

  // One pass in the bag's order: IMU samples in full, image stamps and (raw images) formats.
  std::vector<std::string> topics = spec.image_topics;
  if (!imu_topic.empty()) topics.push_back(imu_topic);
  std::vector<ImuSample> imu;
  std::vector<ImageItem> images;
  struct Problem {
    std::size_t SourceStats::*counter = nullptr;  // nullptr: the image is fine
    std::string message;
  };
  std::vector<Problem> image_problems;  // per entry of `images`
  std::vector<std::size_t> image_k(spec.image_topics.size(), 0);
  rosbag::View view(*bag_, rosbag::TopicQuery(topics));
  for (const rosbag::MessageInstance& m : view) {
    const std::string& topic = m.getTopic();
    if (topic == imu_topic) {
      const auto msg = m.instantiate<sensor_msgs::Imu>();
      if (!msg) throw IoError(fmt::format("{}: topic '{}' holds a different {} definition", path_, topic, kImuType));
      ImuSample s;
      s.t = to_ns(spec.receive_time ? m.getTime() : msg->header.stamp);
      s.gyro = Eigen::Vector3d(msg->angular_velocity.x, msg->angular_velocity.y, msg->angular_velocity.z);
      s.accel = Eigen::Vector3d(msg->linear_acceleration.x, msg->linear_acceleration.y, msg->linear_acceleration.z);
      imu.push_back(s);
      continue;
    }
    const int camera = camera_of_topic.at(topic);
    const auto c = static_cast<std::size_t>(camera);
    ImageItem item{0, camera, image_k[c]++, messages_.size(), compressed[c]};
    Problem problem;
    if (item.compressed) {
      const auto msg = m.instantiate<sensor_msgs::CompressedImage>();
      if (!msg) {
        throw IoError(fmt::format("{}: topic '{}' holds a different {} definition", path_, topic, kCompressedType));
      }
      item.t = to_ns(spec.receive_time ? m.getTime() : msg->header.stamp);
    } else {
      const auto msg = m.instantiate<sensor_msgs::Image>();
      if (!msg) throw IoError(fmt::format("{}: topic '{}' holds a different {} definition", path_, topic, kImageType));
      item.t = to_ns(spec.receive_time ? m.getTime() : msg->header.stamp);
      // The format is checked here (the pixels are converted by next()): what cannot be converted is reported now.
      const cv::Mat grey = grey_from_ros_image(msg->encoding, msg->width, msg->height, msg->step, msg->data.data(),
                                               msg->data.size(), &problem.message);
      const cv::Size expected = c < spec.image_sizes.size() ? spec.image_sizes[c] : cv::Size();
      if (grey.empty()) {
        problem.counter = &SourceStats::undecodable_images;
      } else if (expected.area() > 0 && grey.size() != expected) {
        problem.counter = &SourceStats::wrong_size_images;
        problem.message = fmt::format("image is {}x{}, the calibration of camera {} says {}x{}", grey.cols, grey.rows,
                                      camera, expected.width, expected.height);
      }
    }
    messages_.push_back(m);
    images.push_back(item);
    image_problems.push_back(problem);
  }

  // IMU: finite values, strictly increasing stamps, no long dropouts (the checks of IndexedSource).
  const std::string& imu_where = imu_topic;
  double period_s = spec.checks.imu_rate_hz > 0 ? 1.0 / spec.checks.imu_rate_hz : 0.0;
  if (period_s == 0.0 && imu.size() > 2) {
    std::vector<TimeNs> dts;
    for (std::size_t i = 1; i < imu.size(); ++i) dts.push_back(imu[i].t - imu[i - 1].t);
    std::nth_element(dts.begin(), dts.begin() + static_cast<std::ptrdiff_t>(dts.size() / 2), dts.end());
    period_s = to_seconds(std::max<TimeNs>(dts[dts.size() / 2], 1));
  }
  imu_.reserve(imu.size());
  for (std::size_t i = 0; i < imu.size(); ++i) {
    const ImuSample& s = imu[i];
    const std::string at = where(imu_where, i, s.t);
    if (!s.gyro.allFinite() || !s.accel.allFinite()) {
      reporter_.report(&SourceStats::non_finite, fmt::format("{}: non-finite IMU value", at));
      continue;
    }
    if (const std::string beyond = imu_range_problem(s, spec.checks.imu_range); !beyond.empty()) {
      reporter_.report(&SourceStats::imu_saturated, fmt::format("{}: {}", at, beyond));
      continue;
    }
    if (!imu_.empty()) {
      const TimeNs prev = imu_.back().t;
      if (s.t == prev) {
        reporter_.report(&SourceStats::duplicate_timestamps,
                         fmt::format("{}: duplicate IMU timestamp{}", at, zero_stamp_hint(s.t, spec.receive_time)));
        continue;
      }
      if (s.t < prev) {
        reporter_.report(&SourceStats::backwards_timestamps,
                         fmt::format("{}: IMU timestamp goes backwards (previous {} s){}", at, format_seconds(prev),
                                     zero_stamp_hint(s.t, spec.receive_time)));
        continue;
      }
      if (period_s > 0) {
        const double missing = std::round(to_seconds(s.t - prev) / period_s) - 1.0;
        if (missing > spec.checks.max_imu_dropout) {
          reporter_.report(
              &SourceStats::imu_gaps,
              fmt::format("{}: IMU gap of {:.3f} s (~{} samples missing, more than {})", at, to_seconds(s.t - prev),
                          static_cast<long long>(missing), spec.checks.max_imu_dropout));
          // Nothing to drop for a gap: the sample after it is kept.
        }
      }
    }
    imu_.push_back(s);
  }

  // Images: per camera strictly increasing stamps, then the format and size found above.
  std::vector<TimeNs> last_t(spec.image_topics.size(), 0);
  std::vector<bool> seen(spec.image_topics.size(), false);
  images_.reserve(images.size());
  for (std::size_t i = 0; i < images.size(); ++i) {
    const ImageItem& e = images[i];
    const auto c = static_cast<std::size_t>(e.camera);
    const std::string at = where(spec.image_topics[c], e.k, e.t);
    if (seen[c] && e.t == last_t[c]) {
      reporter_.report(&SourceStats::duplicate_timestamps,
                       fmt::format("{}: duplicate image timestamp{}", at, zero_stamp_hint(e.t, spec.receive_time)));
      continue;
    }
    if (seen[c] && e.t < last_t[c]) {
      reporter_.report(&SourceStats::backwards_timestamps,
                       fmt::format("{}: image timestamp goes backwards (previous {} s){}", at,
                                   format_seconds(last_t[c]), zero_stamp_hint(e.t, spec.receive_time)));
      continue;
    }
    if (seen[c] && static_cast<double>(e.t - last_t[c]) * 1e-9 > kMaxImageJumpS) {  // both stamps >= 0: no overflow
      reporter_.report(&SourceStats::timestamp_jumps,
                       fmt::format("{}: image timestamp is {:.6g} s after the previous one of its topic ({} s): a "
                                   "corrupt timestamp (this one or the previous)", at,
                                   static_cast<double>(e.t - last_t[c]) * 1e-9, format_seconds(last_t[c])));
      continue;
    }
    const Problem& problem = image_problems[i];
    if (problem.counter != nullptr) {
      // As for image files: an image that cannot be decoded is a file problem, a wrong size a data problem.
      reporter_.report(problem.counter, fmt::format("{}: {}", at, problem.message),
                       problem.counter == &SourceStats::undecodable_images);
      continue;
    }
    last_t[c] = e.t;
    seen[c] = true;
    images_.push_back(e);
  }

  // Merge: by time, IMU before images at equal times, then by camera.
  order_.reserve(imu_.size() + images_.size());
  for (std::size_t i = 0; i < imu_.size(); ++i) order_.push_back({imu_[i].t, 0, i});
  for (std::size_t i = 0; i < images_.size(); ++i) order_.push_back({images_[i].t, 1 + images_[i].camera, i});
  std::stable_sort(order_.begin(), order_.end(),
                   [](const Item& a, const Item& b) { return a.t != b.t ? a.t < b.t : a.kind < b.kind; });
}

cv::Mat RosbagSource::decode(const ImageItem& item, std::string* error) const {
  try {
    const rosbag::MessageInstance& m = messages_[item.message];
    if (item.compressed) {
      const auto msg = m.instantiate<sensor_msgs::CompressedImage>();
      if (!msg || msg->data.empty()) {
        *error = "empty compressed image";
        return {};
      }
      std::string why;
      cv::Mat grey = decode_grey_image(msg->data.data(), msg->data.size(), &why, nullptr, /*keep_16bit=*/true);
      if (grey.empty()) *error = fmt::format("compressed image ('{}') {}", msg->format, why);
      return grey;
    }
    const auto msg = m.instantiate<sensor_msgs::Image>();
    return grey_from_ros_image(msg->encoding, msg->width, msg->height, msg->step, msg->data.data(), msg->data.size(),
                               error);
  } catch (const rosbag::BagException& e) {
    *error = fmt::format("cannot be read: {}", e.what());
    return {};
  }
}

std::optional<Measurement> RosbagSource::next() {
  while (pos_ < order_.size()) {
    const Item item = order_[pos_++];
    if (item.kind == 0) {
      ++stats_.imu_samples;
      return imu_[item.index];
    }
    const ImageItem& e = images_[item.index];
    const auto c = static_cast<std::size_t>(e.camera);
    ImageFrame frame;
    frame.t = e.t;
    frame.camera = e.camera;
    frame.path = fmt::format("{}:{}#{}", path_, image_topics_[c], e.k + 1);
    std::string error;
    frame.image = decode(e, &error);
    if (frame.image.depth() == CV_16U) {  // a 16-bit compressed image: scaled by the depth of those before it
      std::string why;
      frame.image = to_grey8(frame.image, &why, &image_bits_);
      if (frame.image.empty()) error = why;
    }
    if (frame.image.empty()) {
      reporter_.report(&SourceStats::undecodable_images,
                       fmt::format("{}: {}", where(image_topics_[c], e.k, e.t), error), true);
      continue;
    }
    if (c < image_sizes_.size() && image_sizes_[c].area() > 0 && frame.image.size() != image_sizes_[c]) {
      reporter_.report(
          &SourceStats::wrong_size_images,
          fmt::format("{}: image is {}x{}, the calibration of camera {} says {}x{}", where(image_topics_[c], e.k, e.t),
                      frame.image.cols, frame.image.rows, e.camera, image_sizes_[c].width, image_sizes_[c].height));
      continue;
    }
    ++stats_.images;
    return frame;
  }
  return std::nullopt;
}

/// The calibration next to a bag: FILE.yaml, calibration.yaml, camchain.yaml, sensor.yaml, FILE/ or mav0/ (EuRoC).
std::string calibration_next_to(const fs::path& bag) {
  const fs::path dir = bag.parent_path().empty() ? fs::path(".") : bag.parent_path();
  const std::string stem = bag.stem().string();
  for (const std::string& name :
       {stem + ".yaml", std::string("calibration.yaml"), std::string("camchain.yaml"), std::string("sensor.yaml")}) {
    if (fs::is_regular_file(dir / name)) return (dir / name).string();
  }
  for (const fs::path& folder : {dir / stem, dir / "mav0"}) {
    if (fs::is_directory(folder / "mav0") || fs::is_regular_file(folder / "cam0" / "sensor.yaml")) {
      return folder.string();
    }
  }
  return {};
}

}  // namespace

Dataset open_rosbag(const std::string& path, const DatasetOptions& o) {
  if (!fs::is_regular_file(path)) throw IoError(fmt::format("{}: bag not found", path));
  Dataset ds;
  ds.kind = "rosbag";
  ds.path = path;
  ds.name = fs::path(path).stem().string();
  const std::string calibration = o.calibration.empty() ? calibration_next_to(path) : o.calibration;
  if (calibration.empty()) {
    throw IoError(
        fmt::format("{}: no calibration: give the calibration option (a rig YAML, Kalibr camchain, EuRoC "
                    "sensor.yaml or EuRoC folder) or put {}.yaml, calibration.yaml, camchain.yaml, "
                    "sensor.yaml or an EuRoC mav0/ folder next to the bag",
                    path, fs::path(path).stem().string()));
  }
  ds.rig = load_rig(calibration, o.cameras);
  if (ds.rig.cameras.empty()) throw ConfigError(fmt::format("{}: no camera selected (option cameras)", path));

  BagReadSpec spec;
  if (o.image_topics.empty()) {
    for (int c : o.cameras) spec.image_topics.push_back(fmt::format("/cam{}/image_raw", c));
  } else if (o.image_topics.size() != o.cameras.size()) {
    throw ConfigError(
        fmt::format("{}: {} image topics for {} cameras (option image_topics: one per camera of the "
                    "cameras option)",
                    path, o.image_topics.size(), o.cameras.size()));
  } else {
    spec.image_topics = o.image_topics;
  }
  spec.imu_topic = o.use_imu ? o.imu_topic : std::string();
  spec.receive_time = o.bag_receive_time;
  spec.checks.policy = o.bad_input;
  spec.checks.imu_rate_hz = ds.rig.imu ? ds.rig.imu->rate_hz : 0.0;
  spec.checks.max_imu_dropout = o.max_imu_dropout;
  if (ds.rig.imu) {
    spec.checks.imu_range = ImuRange::from_full_scale(ds.rig.imu->gyro_saturation, ds.rig.imu->accel_saturation);
  }
  for (const auto& cam : ds.rig.cameras) spec.image_sizes.emplace_back(cam.width, cam.height);
  ds.source = std::make_unique<RosbagSource>(path, spec);

  if (fs::is_directory(calibration)) {
    const fs::path root =
        fs::is_directory(fs::path(calibration) / "mav0") ? fs::path(calibration) / "mav0" : fs::path(calibration);
    const std::string gt = euroc_ground_truth_file(root.string());
    if (!gt.empty()) ds.ground_truth = read_trajectory(gt, TrajectoryFormat::EurocCsv);
  }
  return ds;
}

RosbagWriteStats write_rosbag(Source& source, const Rig& rig, const std::string& path,
                              const RosbagWriteOptions& options) {
  const auto n_cameras = rig.cameras.size();
  if (!options.image_topics.empty() && options.image_topics.size() != n_cameras) {
    throw ConfigError(
        fmt::format("{}: {} image topics for the rig's {} cameras", path, options.image_topics.size(), n_cameras));
  }
  if (!options.camera_frames.empty() && options.camera_frames.size() != n_cameras) {
    throw ConfigError(
        fmt::format("{}: {} camera frames for the rig's {} cameras", path, options.camera_frames.size(), n_cameras));
  }
  rosbag::compression::CompressionType compression = rosbag::compression::Uncompressed;
  if (options.compression == "lz4") {
    compression = rosbag::compression::LZ4;
  } else if (options.compression == "bz2") {
    compression = rosbag::compression::BZ2;
  } else if (options.compression != "none") {
    throw ConfigError(fmt::format("compression = '{}' must be none, lz4 or bz2", options.compression));
  }
  std::vector<std::string> topics(n_cameras);
  std::vector<std::string> frames(n_cameras);
  for (std::size_t c = 0; c < n_cameras; ++c) {
    topics[c] = options.image_topics.empty() ? fmt::format("/cam{}/image_raw", c) : options.image_topics[c];
    frames[c] = !options.camera_frames.empty() ? options.camera_frames[c]
                : !rig.cameras[c].name.empty() ? rig.cameras[c].name
                                               : fmt::format("cam{}", c);
  }
  // σ² of one sample = density² · rate (continuous-time white noise sampled at the IMU rate); 0 = unknown.
  double gyro_var = 0.0;
  double accel_var = 0.0;
  if (rig.imu && rig.imu->rate_hz > 0) {
    gyro_var = rig.imu->gyro_noise_density * rig.imu->gyro_noise_density * rig.imu->rate_hz;
    accel_var = rig.imu->accel_noise_density * rig.imu->accel_noise_density * rig.imu->rate_hz;
  }

  const fs::path parent = fs::path(path).parent_path();
  if (!parent.empty()) fs::create_directories(parent);
  RosbagWriteStats stats;
  rosbag::Bag bag;
  try {
    bag.open(path, rosbag::bagmode::Write);
    bag.setCompression(compression);
    std::vector<std::uint32_t> seq(n_cameras, 0);
    std::uint32_t imu_seq = 0;
    while (auto m = source.next()) {
      const TimeNs t = time_of(*m);
      if (t <= 0 || t / kNsPerSecond > TimeNs{0xFFFFFFFF}) {
        throw DataError(fmt::format("{}: time {} s does not fit a ROS time (must be > 0)", path, format_seconds(t)));
      }
      const ros::Time stamp = to_ros_time(t);
      if (const auto* s = std::get_if<ImuSample>(&*m)) {
        sensor_msgs::Imu msg;
        msg.header.seq = imu_seq++;
        msg.header.stamp = stamp;
        msg.header.frame_id = options.imu_frame;
        msg.orientation_covariance[0] = -1.0;  // no orientation estimate
        msg.angular_velocity.x = s->gyro.x();
        msg.angular_velocity.y = s->gyro.y();
        msg.angular_velocity.z = s->gyro.z();
        msg.linear_acceleration.x = s->accel.x();
        msg.linear_acceleration.y = s->accel.y();
        msg.linear_acceleration.z = s->accel.z();
        for (int k = 0; k < 3; ++k) {
          msg.angular_velocity_covariance[static_cast<std::size_t>(4 * k)] = gyro_var;
          msg.linear_acceleration_covariance[static_cast<std::size_t>(4 * k)] = accel_var;
        }
        bag.write(options.imu_topic, stamp, msg);
        ++stats.imu_samples;
        continue;
      }
      const auto& frame = std::get<ImageFrame>(*m);
      if (frame.camera < 0 || static_cast<std::size_t>(frame.camera) >= n_cameras) {
        throw ConfigError(
            fmt::format("{}: image of camera {} but the rig has {} camera(s)", path, frame.camera, n_cameras));
      }
      if (frame.image.type() != CV_8UC1 || frame.image.empty()) {
        throw DataError(fmt::format("{}: image {} at t = {} s is not 8-bit grey", path, frame.path, format_seconds(t)));
      }
      const auto c = static_cast<std::size_t>(frame.camera);
      sensor_msgs::Image msg;
      msg.header.seq = seq[c]++;
      msg.header.stamp = stamp;
      msg.header.frame_id = frames[c];
      msg.height = static_cast<std::uint32_t>(frame.image.rows);
      msg.width = static_cast<std::uint32_t>(frame.image.cols);
      msg.encoding = "mono8";
      msg.is_bigendian = 0;
      msg.step = msg.width;
      msg.data.resize(static_cast<std::size_t>(msg.step) * msg.height);
      for (int r = 0; r < frame.image.rows; ++r) {
        std::copy_n(frame.image.ptr<std::uint8_t>(r), msg.width,
                    msg.data.data() + static_cast<std::size_t>(r) * msg.step);
      }
      bag.write(topics[c], stamp, msg);
      ++stats.images;
    }
    bag.close();
  } catch (const rosbag::BagException& e) {
    throw IoError(fmt::format("{}: cannot write the bag: {}", path, e.what()));
  }
  if (options.write_calibration) write_rig_yaml(fs::path(path).replace_extension(".yaml").string(), rig);
  return stats;
}

}  // namespace rtslam::io
