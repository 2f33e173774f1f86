// ROS1 bags (src/rtslam/io/rosbag_source.hpp): image encodings (everywhere), and in builds with ROS the round trip
// simulator -> write_rosbag -> the rosbag: reader (same IMU samples, same pixels, same times), the reader's checks
// and options on hand-made bags, the EuRoC excerpt through a bag, and the pipeline on a bag against the same run on
// the simulator. Without ROS the bag tests skip with a message.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "io/io_test_util.hpp"
#include "recorded_source.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/rosbag_source.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/sim/simulation.hpp"
#if RTSLAM_TEST_HAVE_ROS
#include "bag_fixture.hpp"
#endif

namespace rtslam::io {
namespace {

namespace fs = std::filesystem;
using ros_test::Recorded;
using test::TempDir;

#define REQUIRE_ROS()                                                                    \
  if (!rosbag_supported())                                                               \
  GTEST_SKIP() << "built without ROS1: bag tests skipped (scripts/deps.sh installs the " \
                  "packages, docs/ros.md)"

// ------------------------------------------------------------------------------------------ image encodings

std::vector<std::uint8_t> bytes(const cv::Mat& m) {
  std::vector<std::uint8_t> v;
  for (int r = 0; r < m.rows; ++r)
    v.insert(v.end(), m.ptr<std::uint8_t>(r), m.ptr<std::uint8_t>(r) + m.cols * m.elemSize());
  return v;
}

TEST(RosImage, Mono8IsCopiedWithoutTheRowPadding) {
  // 3x2 pixels, rows of 4 bytes (one byte of padding).
  const std::vector<std::uint8_t> data = {1, 2, 3, 99, 4, 5, 6, 99};
  std::string error;
  const cv::Mat grey = grey_from_ros_image("mono8", 3, 2, 4, data.data(), data.size(), &error);
  ASSERT_FALSE(grey.empty()) << error;
  EXPECT_EQ(grey.type(), CV_8UC1);
  EXPECT_EQ(bytes(grey), (std::vector<std::uint8_t>{1, 2, 3, 4, 5, 6}));
}

TEST(RosImage, ColourEncodingsUseOpenCvsWeightsWhateverTheChannelOrder) {
  cv::Mat bgr(5, 7, CV_8UC3);
  cv::randu(bgr, 0, 255);
  cv::Mat rgb, bgra, rgba, expected;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  cv::cvtColor(bgr, bgra, cv::COLOR_BGR2BGRA);
  cv::cvtColor(bgr, rgba, cv::COLOR_BGR2RGBA);
  cv::cvtColor(bgr, expected, cv::COLOR_BGR2GRAY);
  const auto convert = [](const std::string& enc, const cv::Mat& m) {
    const auto b = bytes(m);
    std::string error;
    cv::Mat g = grey_from_ros_image(enc, static_cast<std::uint32_t>(m.cols), static_cast<std::uint32_t>(m.rows),
                                    static_cast<std::uint32_t>(m.cols * m.elemSize()), b.data(), b.size(), &error);
    EXPECT_FALSE(g.empty()) << enc << ": " << error;
    return g;
  };
  for (const auto& [enc, m] : {std::pair<std::string, cv::Mat>{"bgr8", bgr},
                               {"rgb8", rgb},
                               {"bgra8", bgra},
                               {"rgba8", rgba},
                               {"8UC3", bgr},
                               {"8UC4", bgra}}) {
    const cv::Mat g = convert(enc, m);
    ASSERT_EQ(g.size(), expected.size()) << enc;
    EXPECT_EQ(cv::norm(g, expected, cv::NORM_INF), 0.0) << enc;
  }
}

TEST(RosImage, BayerPatternsAreDemosaicedToGrey) {
  const cv::Mat flat(6, 8, CV_8UC1, cv::Scalar(120));  // a grey scene gives the same value on every photosite
  const auto b = bytes(flat);
  for (const char* enc : {"bayer_rggb8", "bayer_bggr8", "bayer_gbrg8", "bayer_grbg8"}) {
    std::string error;
    const cv::Mat g = grey_from_ros_image(enc, 8, 6, 8, b.data(), b.size(), &error);
    ASSERT_FALSE(g.empty()) << enc << ": " << error;
    EXPECT_EQ(g.size(), flat.size()) << enc;
    EXPECT_EQ(cv::norm(g, flat, cv::NORM_INF), 0.0) << enc;
  }
}

TEST(RosImage, RefusesOtherEncodingsAndInconsistentBuffersWithOneLine) {
  const std::vector<std::uint8_t> data(64, 7);
  std::string error;
  EXPECT_TRUE(grey_from_ros_image("mono16", 4, 4, 8, data.data(), 32, &error).empty());
  EXPECT_NE(error.find("'mono16' is not supported"), std::string::npos) << error;
  EXPECT_NE(error.find("mono8"), std::string::npos) << error;                          // lists what is supported
  EXPECT_TRUE(grey_from_ros_image("rgb8", 4, 4, 8, data.data(), 32, &error).empty());  // step < 3 * width
  EXPECT_NE(error.find("step 8 is less than"), std::string::npos) << error;
  EXPECT_TRUE(grey_from_ros_image("mono8", 4, 4, 4, data.data(), 15, &error).empty());
  EXPECT_NE(error.find("15 bytes"), std::string::npos) << error;
  EXPECT_TRUE(grey_from_ros_image("mono8", 0, 4, 4, data.data(), 0, &error).empty());
  EXPECT_NE(error.find("empty"), std::string::npos) << error;
  EXPECT_TRUE(grey_from_ros_image("mono8", 4, 4, 4, nullptr, 16, nullptr).empty());  // no error string wanted
}

// ------------------------------------------------------------------------------------------ without ROS

TEST(Rosbag, WithoutRosTheKindSaysSo) {
  if (rosbag_supported()) GTEST_SKIP() << "this build has ROS: the stubs are not compiled";
  TempDir dir;
  test::write_text(dir / "x.bag", "not a bag");
  EXPECT_THROW_WITH(open_dataset("rosbag:" + (dir / "x.bag")), ConfigError, "without ROS support");
}

// ------------------------------------------------------------------------------------------ round trips

/// The handheld preset (camera at 20 Hz, IMU at 200 Hz) shortened to 0.5 s, and its stream: made once for the
/// tests that need a sequence (building a simulation takes seconds under the sanitizers).
struct ShortSim {
  std::shared_ptr<const sim::Simulation> sim;
  std::unique_ptr<Recorded> stream;
  const Rig& rig() const { return sim->rig(); }
  std::unique_ptr<Source> make_source() const { return stream->replay(); }
};

const ShortSim& short_sim() {
  static const ShortSim s = [] {
    sim::SimConfig c = sim::SimConfig::preset("handheld");
    c.duration_s = 0.5;
    ShortSim x;
    x.sim = sim::Simulation::create(c);
    x.stream = std::make_unique<Recorded>(*x.sim->make_source());
    return x;
  }();
  return s;
}

/// Reads both streams to the end: the same measurements, bit for bit, at the same times.
void expect_same_stream(Source& expected, Source& actual, std::size_t* images = nullptr, std::size_t* imu = nullptr) {
  std::size_t n_images = 0, n_imu = 0;
  for (std::size_t k = 0;; ++k) {
    const auto a = expected.next();
    const auto b = actual.next();
    ASSERT_EQ(a.has_value(), b.has_value()) << "measurement " << k;
    if (!a) break;
    ASSERT_EQ(a->index(), b->index()) << "measurement " << k << " at t = " << time_of(*a);
    EXPECT_EQ(time_of(*a), time_of(*b)) << "measurement " << k;
    if (const auto* s = std::get_if<ImuSample>(&*a)) {
      const auto& r = std::get<ImuSample>(*b);
      EXPECT_EQ(s->gyro, r.gyro) << "IMU sample at t = " << s->t;
      EXPECT_EQ(s->accel, r.accel) << "IMU sample at t = " << s->t;
      ++n_imu;
    } else {
      const auto& f = std::get<ImageFrame>(*a);
      const auto& g = std::get<ImageFrame>(*b);
      EXPECT_EQ(f.camera, g.camera);
      ASSERT_EQ(f.image.size(), g.image.size()) << "image at t = " << f.t;
      ASSERT_EQ(g.image.type(), CV_8UC1);
      EXPECT_EQ(cv::norm(f.image, g.image, cv::NORM_INF), 0.0) << "image at t = " << f.t;
      ++n_images;
    }
  }
  if (images != nullptr) *images = n_images;
  if (imu != nullptr) *imu = n_imu;
}

TEST(Rosbag, SimulatedSequenceRoundTripsBitForBit) {
  REQUIRE_ROS();
  TempDir dir;
  const ShortSim& sim = short_sim();
  const std::string bag = dir / "handheld.bag";
  const RosbagWriteStats written = write_rosbag(*sim.make_source(), sim.rig(), bag);
  EXPECT_EQ(written.images, sim.sim->image_times().size());
  EXPECT_EQ(written.imu_samples, sim.sim->imu_samples().size());
  ASSERT_TRUE(fs::is_regular_file(dir / "handheld.yaml")) << "the rig YAML next to the bag";

  Dataset ds = open_dataset("rosbag:" + bag);  // the calibration is found next to the bag
  EXPECT_EQ(ds.kind, "rosbag");
  EXPECT_EQ(ds.name, "handheld");
  EXPECT_EQ(ds.source->image_count(), sim.sim->image_times().size());
  ASSERT_EQ(ds.rig.cameras.size(), 1u);
  const CameraCalibration& cam = ds.rig.cameras[0];
  const CameraCalibration& ref = sim.rig().cameras[0];
  EXPECT_EQ(cam.width, ref.width);
  EXPECT_EQ(cam.fx, ref.fx);
  EXPECT_EQ(cam.distortion_coeffs, ref.distortion_coeffs);
  EXPECT_TRUE(cam.T_RS.isApprox(ref.T_RS, 1e-15));
  ASSERT_TRUE(ds.rig.imu.has_value());
  EXPECT_EQ(ds.rig.imu->gyro_noise_density, sim.rig().imu->gyro_noise_density);

  std::size_t images = 0, imu = 0;
  expect_same_stream(*sim.make_source(), *ds.source, &images, &imu);
  EXPECT_EQ(images, sim.sim->image_times().size());
  EXPECT_EQ(imu, sim.sim->imu_samples().size());
  EXPECT_EQ(ds.source->stats().problems(), 0u) << ds.source->stats().summary();
  EXPECT_EQ(ds.source->stats().images, images);

  // A kind detected from the .bag extension, and lz4 chunks read the same.
  const std::string lz4 = dir / "lz4.bag";
  RosbagWriteOptions wo;
  wo.compression = "lz4";
  write_rosbag(*sim.make_source(), sim.rig(), lz4, wo);
  Dataset ds_lz4 = open_dataset(lz4);
  EXPECT_EQ(ds_lz4.kind, "rosbag");
  expect_same_stream(*sim.make_source(), *ds_lz4.source);
}

TEST(Rosbag, TopicsAreOptionsAndAMissingTopicListsTheBagsTopics) {
  REQUIRE_ROS();
  TempDir dir;
  const ShortSim& sim = short_sim();
  const std::string bag = dir / "renamed.bag";
  RosbagWriteOptions wo;
  wo.image_topics = {"/camera/image_raw"};
  wo.imu_topic = "/imu";
  write_rosbag(*sim.make_source(), sim.rig(), bag, wo);

  EXPECT_THROW_WITH(open_dataset("rosbag:" + bag), IoError, "no image topic '/cam0/image_raw'");
  const std::size_t n_images = sim.sim->image_times().size();
  EXPECT_THROW_WITH(open_dataset("rosbag:" + bag), IoError,
                    "/camera/image_raw (sensor_msgs/Image, " + std::to_string(n_images) + " messages)");
  DatasetOptions o;
  o.image_topics = {"/camera/image_raw"};
  o.imu_topic = "/imu";
  Dataset ds = open_dataset("rosbag:" + bag, o);
  expect_same_stream(*sim.make_source(), *ds.source);
  // Without the IMU (a monocular run): images only.
  o.use_imu = false;
  Dataset mono = open_dataset("rosbag:" + bag, o);
  std::size_t imu = 0;
  while (auto m = mono.source->next()) imu += std::holds_alternative<ImuSample>(*m) ? 1 : 0;
  EXPECT_EQ(imu, 0u);
  EXPECT_EQ(mono.source->stats().images, n_images);
  // One topic per camera of the cameras option.
  o.image_topics = {"/camera/image_raw", "/other"};
  EXPECT_THROW_WITH(open_dataset("rosbag:" + bag, o), ConfigError, "2 image topics for 1 cameras");
}

TEST(Rosbag, WithoutCalibrationTheMessageSaysWhereItLooked) {
  REQUIRE_ROS();
  TempDir dir;
  const ShortSim& sim = short_sim();
  RosbagWriteOptions wo;
  wo.write_calibration = false;
  write_rosbag(*sim.make_source(), sim.rig(), dir / "bare.bag", wo);
  EXPECT_FALSE(fs::exists(dir / "bare.yaml"));
  EXPECT_THROW_WITH(open_dataset("rosbag:" + (dir / "bare.bag")), IoError, "give the calibration option");
  // The calibration option: our rig YAML written elsewhere.
  fs::create_directories(dir / "rig");
  write_rig_yaml(dir / "rig/my_rig.yaml", sim.rig());
  DatasetOptions o;
  o.calibration = dir / "rig/my_rig.yaml";
  Dataset ds = open_dataset("rosbag:" + (dir / "bare.bag"), o);
  EXPECT_EQ(ds.rig.cameras.at(0).fx, sim.rig().cameras[0].fx);
  wo.compression = "zip";
  EXPECT_THROW_WITH(write_rosbag(*sim.make_source(), sim.rig(), dir / "x.bag", wo), ConfigError, "compression = 'zip'");
}

TEST(Rosbag, EurocExcerptThroughABagKeepsEveryMeasurementAndTheGroundTruth) {
  REQUIRE_ROS();
  const std::string euroc = test::euroc_dir();
  if (!fs::exists(euroc)) GTEST_SKIP() << "dataset " << euroc << " not found";
  TempDir dir;
  Dataset original = open_dataset("euroc:" + euroc);
  const std::string bag = dir / "V1_01_excerpt.bag";
  RosbagWriteOptions wo;
  wo.write_calibration = false;  // read the calibration from the EuRoC folder, as users of EuRoC's bags do
  const RosbagWriteStats written = write_rosbag(*original.source, original.rig, bag, wo);
  EXPECT_GT(written.images, 90u);
  EXPECT_GT(written.imu_samples, 900u);

  DatasetOptions o;
  o.calibration = euroc;
  Dataset ds = open_dataset("rosbag:" + bag, o);
  ASSERT_EQ(ds.rig.cameras.size(), 1u);
  EXPECT_TRUE(ds.rig.cameras[0].T_RS.isApprox(original.rig.cameras[0].T_RS, 1e-15));
  EXPECT_EQ(ds.rig.imu->rate_hz, original.rig.imu->rate_hz);
  ASSERT_TRUE(ds.ground_truth.has_value());
  EXPECT_EQ(ds.ground_truth->poses.size(), original.ground_truth->poses.size());
  Dataset again = open_dataset("euroc:" + euroc);
  std::size_t images = 0, imu = 0;
  expect_same_stream(*again.source, *ds.source, &images, &imu);
  EXPECT_EQ(images, written.images);
  EXPECT_EQ(imu, written.imu_samples);
}

// ------------------------------------------------------------------------------------------ hand-made bags

#if RTSLAM_TEST_HAVE_ROS

using ros_test::RawCompressed;
using ros_test::RawImage;
using ros_test::RawImu;
using ros_test::RawMessage;

constexpr TimeNs kT0 = 1'000'000'000;  // 1 s
constexpr TimeNs kMs = 1'000'000;

/// A 4x4 camera (and a 200 Hz IMU) as rtslam rig YAML.
std::string write_small_rig(const TempDir& dir) {
  Rig rig;
  CameraCalibration cam;
  cam.name = "cam0";
  cam.width = 4;
  cam.height = 4;
  cam.fx = cam.fy = 10.0;
  cam.cx = cam.cy = 2.0;
  rig.cameras.push_back(cam);
  ImuCalibration imu;
  imu.rate_hz = 200.0;
  imu.gyro_noise_density = 1e-3;
  imu.accel_noise_density = 1e-2;
  rig.imu = imu;
  const std::string path = dir / "rig.yaml";
  write_rig_yaml(path, rig);
  return path;
}

RawImage mono(TimeNs t, int w = 4, int h = 4, std::uint8_t value = 50) {
  RawImage m;
  m.stamp = t;
  m.width = static_cast<std::uint32_t>(w);
  m.height = static_cast<std::uint32_t>(h);
  m.step = m.width;
  m.data.assign(static_cast<std::size_t>(w * h), value);
  return m;
}

RawImu imu_at(TimeNs t, double gx = 0.1) {
  RawImu m;
  m.stamp = t;
  m.gyro = Eigen::Vector3d(gx, 0.0, 0.0);
  m.accel = Eigen::Vector3d(0.0, 0.0, 9.81);
  return m;
}

TEST(Rosbag, BadInputIsReportedOrSkippedAndCountedLikeTheOtherReaders) {
  REQUIRE_ROS();
  TempDir dir;
  const std::string bag = dir / "bad.bag";
  RawImage mono16 = mono(kT0 + 12 * kMs);
  mono16.encoding = "mono16";
  mono16.step = 8;
  mono16.data.assign(32, 1);
  RawImu nan = imu_at(kT0 + 10 * kMs, std::numeric_limits<double>::quiet_NaN());
  std::vector<RawMessage> messages = {imu_at(kT0),
                                      mono(kT0),
                                      imu_at(kT0 + 5 * kMs),
                                      imu_at(kT0 + 5 * kMs),  // duplicate
                                      mono(kT0),              // duplicate
                                      nan,
                                      imu_at(kT0 + 4 * kMs),  // backwards
                                      imu_at(kT0 + 10 * kMs),
                                      mono(kT0 + 10 * kMs, 6, 4),  // wrong size
                                      mono16,                      // undecodable
                                      imu_at(kT0 + 15 * kMs),
                                      mono(kT0 + 20 * kMs),
                                      mono(kT0 + 15 * kMs),  // backwards
                                      mono(kT0 + 30 * kMs)};
  // The bag's order is its receive times (rosbag::View sorts by them): received in the order above, 1 ms apart,
  // whatever the header stamps say.
  for (std::size_t i = 0; i < messages.size(); ++i) {
    std::visit([&](auto& m) { m.receive = 2 * kT0 + static_cast<TimeNs>(i) * kMs; }, messages[i]);
  }
  ros_test::write_bag(bag, messages);
  DatasetOptions o;
  o.calibration = write_small_rig(dir);
  // Error (default): the first problem stops the reader, naming the bag, the topic and the message.
  EXPECT_THROW_WITH(open_dataset("rosbag:" + bag, o), DataError, bag + " /imu0 message 3 (t = 1.005000000 s)");
  EXPECT_THROW_WITH(open_dataset("rosbag:" + bag, o), DataError, "duplicate IMU timestamp");
  // Skip: every problem counted once, the rest streamed in time order, IMU first at equal times.
  o.bad_input = BadInputPolicy::Skip;
  Dataset ds = open_dataset("rosbag:" + bag, o);
  std::vector<std::pair<TimeNs, bool>> got;  // (t, is image)
  while (auto m = ds.source->next()) got.emplace_back(time_of(*m), std::holds_alternative<ImageFrame>(*m));
  const std::vector<std::pair<TimeNs, bool>> expected = {{kT0, false},
                                                         {kT0, true},
                                                         {kT0 + 5 * kMs, false},
                                                         {kT0 + 10 * kMs, false},
                                                         {kT0 + 15 * kMs, false},
                                                         {kT0 + 20 * kMs, true},
                                                         {kT0 + 30 * kMs, true}};
  EXPECT_EQ(got, expected);
  const SourceStats& s = ds.source->stats();
  EXPECT_EQ(s.duplicate_timestamps, 2u);
  EXPECT_EQ(s.backwards_timestamps, 2u);
  EXPECT_EQ(s.non_finite, 1u);
  EXPECT_EQ(s.wrong_size_images, 1u);
  EXPECT_EQ(s.undecodable_images, 1u);
  EXPECT_EQ(s.imu_gaps, 0u);
  EXPECT_EQ(s.images, 3u);
  EXPECT_EQ(s.imu_samples, 4u);
  EXPECT_EQ(s.messages.size(), s.problems());
  EXPECT_NE(s.summary().find("1 undecodable image"), std::string::npos) << s.summary();
}

TEST(Rosbag, ImuDropoutsAreGapsAndAGapDropsNothing) {
  REQUIRE_ROS();
  TempDir dir;
  const std::string bag = dir / "gap.bag";
  std::vector<RawMessage> messages;
  for (int k = 0; k < 10; ++k) messages.push_back(imu_at(kT0 + 5 * kMs * k));
  for (int k = 15; k < 20; ++k) messages.push_back(imu_at(kT0 + 5 * kMs * k));  // 5 samples missing
  messages.push_back(mono(kT0 + 50 * kMs));
  ros_test::write_bag(bag, messages);
  DatasetOptions o;
  o.calibration = write_small_rig(dir);
  EXPECT_THROW_WITH(open_dataset("rosbag:" + bag, o), DataError, "IMU gap of 0.030 s");
  o.max_imu_dropout = 5;
  EXPECT_NO_THROW(open_dataset("rosbag:" + bag, o));
  o.max_imu_dropout = 3;
  o.bad_input = BadInputPolicy::Skip;
  Dataset ds = open_dataset("rosbag:" + bag, o);
  while (ds.source->next()) {
  }
  EXPECT_EQ(ds.source->stats().imu_gaps, 1u);
  EXPECT_EQ(ds.source->stats().imu_samples, 15u);
}

TEST(Rosbag, UnstampedMessagesPointToTheReceiveTimesOption) {
  REQUIRE_ROS();
  TempDir dir;
  const std::string bag = dir / "unstamped.bag";
  RawImage a = mono(0);
  a.receive = kT0;
  RawImage b = mono(0);
  b.receive = kT0 + 50 * kMs;
  ros_test::write_bag(bag, {a, b});
  DatasetOptions o;
  o.calibration = write_small_rig(dir);
  o.use_imu = false;
  EXPECT_THROW_WITH(open_dataset("rosbag:" + bag, o), DataError, "option bag_receive_time");
  o.bag_receive_time = true;
  Dataset ds = open_dataset("rosbag:" + bag, o);
  std::vector<TimeNs> times;
  while (auto m = ds.source->next()) times.push_back(time_of(*m));
  EXPECT_EQ(times, (std::vector<TimeNs>{kT0, kT0 + 50 * kMs}));
}

TEST(Rosbag, CompressedImagesAreDecodedWhenTheStreamReachesThem) {
  REQUIRE_ROS();
  TempDir dir;
  cv::Mat pixels(4, 4, CV_8UC1);
  cv::randu(pixels, 0, 255);
  std::vector<std::uint8_t> png;
  ASSERT_TRUE(io::codecs::imencode(".png", pixels, png));
  RawCompressed good;
  good.stamp = kT0;
  good.data = png;
  RawCompressed broken = good;
  broken.stamp = kT0 + 50 * kMs;
  broken.data.resize(png.size() / 2);
  const std::string bag = dir / "compressed.bag";
  ros_test::write_bag(bag, {good, broken});
  DatasetOptions o;
  o.calibration = write_small_rig(dir);
  o.bad_input = BadInputPolicy::Skip;
  Dataset ds = open_dataset("rosbag:" + bag, o);
  EXPECT_EQ(ds.source->image_count(), 2u);
  const auto first = ds.source->next();
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(cv::norm(std::get<ImageFrame>(*first).image, pixels, cv::NORM_INF), 0.0);
  EXPECT_FALSE(ds.source->next().has_value());
  EXPECT_EQ(ds.source->stats().undecodable_images, 1u);
  o.bad_input = BadInputPolicy::Error;
  Dataset strict = open_dataset("rosbag:" + bag, o);
  strict.source->next();
  EXPECT_THROW_WITH(strict.source->next(), IoError, "cannot be decoded");
}

TEST(Rosbag, ATopicOfAnotherTypeIsAConfigError) {
  REQUIRE_ROS();
  TempDir dir;
  RawImu on_image_topic = imu_at(kT0);
  on_image_topic.topic = "/cam0/image_raw";
  ros_test::write_bag(dir / "types.bag", {on_image_topic});
  DatasetOptions o;
  o.calibration = write_small_rig(dir);
  EXPECT_THROW_WITH(open_dataset("rosbag:" + (dir / "types.bag"), o), ConfigError,
                    "topic '/cam0/image_raw' is sensor_msgs/Imu");
  test::write_text(dir / "text.bag", "#ROSBAG V2.0\ngarbage");
  EXPECT_THROW_WITH(open_dataset("rosbag:" + (dir / "text.bag"), o), IoError, "cannot be read as a ROS bag");
}

#else

TEST(Rosbag, HandMadeBagsNeedRos) {
  GTEST_SKIP() << "built without ROS1: the hand-made bag tests are not compiled (scripts/deps.sh, docs/ros.md)";
}

#endif

// ------------------------------------------------------------------------------------------ the pipeline

/// The pipeline on a simulated sequence, and on the same sequence written to a bag and read back, with the
/// simulator's ground truth attached to both: the same measurements give the same trajectory, bit for bit.
void expect_same_run_through_a_bag(const std::string& config, double duration_s, bool use_imu) {
  TempDir dir;
  pipeline::ImageSlamOptions o = pipeline::load_image_slam_config(RTSLAM_SOURCE_DIR "/" + config);
  o.sim_duration_s = duration_s;
  const std::string bag = dir / "run.bag";
  Dataset sim = pipeline::make_sim_dataset(o);
  const Recorded stream(*sim.source);
  write_rosbag(*stream.replay(), sim.rig, bag);
  sim.source = stream.replay();
  const pipeline::ImageSlamResult expected = pipeline::run_image_slam(sim, o);
  DatasetOptions dopt;
  dopt.use_imu = use_imu;
  Dataset from_bag = open_dataset("rosbag:" + bag, dopt);
  from_bag.ground_truth = sim.ground_truth;
  const pipeline::ImageSlamResult actual = pipeline::run_image_slam(from_bag, o);
  ASSERT_GT(expected.estimate.poses.size(), 10u);
  ASSERT_EQ(actual.estimate.poses.size(), expected.estimate.poses.size());
  for (std::size_t k = 0; k < expected.estimate.poses.size(); ++k) {
    const StampedPose& a = expected.estimate.poses[k];
    const StampedPose& b = actual.estimate.poses[k];
    EXPECT_EQ(a.t, b.t) << "frame " << k;
    EXPECT_EQ(a.p_WR, b.p_WR) << "frame " << k;
    EXPECT_EQ(a.q_WR.coeffs(), b.q_WR.coeffs()) << "frame " << k;
  }
  EXPECT_EQ(actual.landmarks_final, expected.landmarks_final);
  EXPECT_EQ(actual.imu_samples, expected.imu_samples);
}

TEST(RosbagPipeline, MonocularRunOnTheBagEqualsTheRunOnTheSimulator) {
  REQUIRE_ROS();
  expect_same_run_through_a_bag("config/sim_mono.yaml", 1.5, false);
}

TEST(RosbagPipeline, InertialRunOnTheBagEqualsTheRunOnTheSimulator) {
  REQUIRE_ROS();
  expect_same_run_through_a_bag("config/sim_mono_imu.yaml", 1.5, true);
}

}  // namespace
}  // namespace rtslam::io
