// Decoding ahead (io/prefetch.hpp) changes nothing in the stream: the same measurements in the same order with the
// same pixels, the same stats, the same error at the same point; and it shuts down when the consumer stops early.
// Not timed (the figures are from bench/io and `rtslam bench --pipeline`); run under ASan/UBSan, and by hand under
// TSan (docs/performance.md).
#include <gtest/gtest.h>

#include <filesystem>
#include <variant>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*, cv::IMWRITE_*

#include "io_test_util.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/prefetch.hpp"
#include "rtslam/io/writers.hpp"

namespace rtslam::io {
namespace {

namespace fs = std::filesystem;
using test::read_text;
using test::TempDir;
using test::write_text;

constexpr TimeNs kT0 = 2'000'000'000'000;
constexpr int kImu = 400;  // 2 s at 200 Hz; images on both cameras every 10th sample: 40 each

/// A small EuRoC folder with two cameras (images interleaved with each other and with the IMU), textured images.
std::string make_stereo_dataset(const TempDir& dir) {
  Rig rig;
  for (int c = 0; c < 2; ++c) rig.cameras.push_back(test::small_camera(fmt::format("cam{}", c)));
  rig.imu = test::small_imu();
  const std::string root = dir / "seq";
  EurocWriter w(root, rig);
  cv::RNG rng(7);
  for (int i = 0; i < kImu; ++i) {
    ImuSample s;
    s.t = kT0 + i * 5'000'000;
    s.gyro = Eigen::Vector3d(0.01 * i, 0.1, -0.02);
    s.accel = Eigen::Vector3d(9.81, 0.001 * i, 0.0);
    w.add_imu(s);
    if (i % 10 == 0) {
      for (int c = 0; c < 2; ++c) {
        cv::Mat img(48, 64, CV_8UC1);
        rng.fill(img, cv::RNG::UNIFORM, 0, 256);
        w.add_image(c, s.t, img);
      }
    }
  }
  w.close();
  return root;
}

std::string image_path(const std::string& root, int camera, int k) {
  return fmt::format("{}/mav0/cam{}/data/{}.png", root, camera, kT0 + k * 10 * 5'000'000);
}

/// Everything a stream yielded until its end or its first error (the message, empty if none).
struct Drained {
  std::vector<Measurement> items;
  std::string error;
  SourceStats stats;
};

Drained drain(Source& s) {
  Drained d;
  try {
    while (auto m = s.next()) d.items.push_back(std::move(*m));
  } catch (const std::exception& e) {
    d.error = e.what();
  }
  d.stats = s.stats();
  return d;
}

/// Every measurement equal: kind, time, IMU values bit for bit, image camera, path, size and every pixel.
void expect_same(const Drained& a, const Drained& b) {
  ASSERT_EQ(a.items.size(), b.items.size());
  for (std::size_t i = 0; i < a.items.size(); ++i) {
    ASSERT_EQ(a.items[i].index(), b.items[i].index()) << "measurement " << i;
    ASSERT_EQ(time_of(a.items[i]), time_of(b.items[i])) << "measurement " << i;
    if (const auto* s = std::get_if<ImuSample>(&a.items[i])) {
      const auto& r = std::get<ImuSample>(b.items[i]);
      EXPECT_EQ(s->gyro, r.gyro) << "measurement " << i;
      EXPECT_EQ(s->accel, r.accel) << "measurement " << i;
    } else {
      const auto& x = std::get<ImageFrame>(a.items[i]);
      const auto& y = std::get<ImageFrame>(b.items[i]);
      EXPECT_EQ(x.camera, y.camera) << "measurement " << i;
      EXPECT_EQ(x.path, y.path) << "measurement " << i;
      ASSERT_EQ(x.image.size(), y.image.size()) << "measurement " << i;
      ASSERT_EQ(x.image.type(), y.image.type()) << "measurement " << i;
      EXPECT_EQ(cv::norm(x.image, y.image, cv::NORM_INF), 0.0) << "measurement " << i;
    }
  }
  EXPECT_EQ(a.error, b.error);
  EXPECT_EQ(a.stats.to_json(), b.stats.to_json());
}

DatasetOptions stereo_options(BadInputPolicy policy = BadInputPolicy::Error) {
  DatasetOptions o;
  o.cameras = {0, 1};
  o.bad_input = policy;
  return o;
}

/// The stream of `root` read plainly, with DecodeAhead (threads, depth), and through a PrefetchSource.
void expect_prefetch_changes_nothing(const std::string& root, const DatasetOptions& o) {
  Dataset plain = open_dataset(root, o);
  const Drained ref = drain(*plain.source);
  for (const auto& [threads, depth] : {std::pair{1, 1}, {2, 0}, {3, 2}}) {
    SCOPED_TRACE(fmt::format("DecodeAhead: {} threads, depth {}", threads, depth));
    Dataset ds = open_dataset(root, o);
    ASSERT_TRUE(ds.source->prefetch(PrefetchOptions{.threads = threads, .depth = static_cast<std::size_t>(depth)}));
    expect_same(ref, drain(*ds.source));
  }
  {
    SCOPED_TRACE("PrefetchSource");
    Dataset ds = open_dataset(root, o);
    PrefetchSource wrapped(std::move(ds.source), 3);
    EXPECT_EQ(wrapped.image_count(), plain.source->image_count());
    expect_same(ref, drain(wrapped));
  }
}

TEST(Prefetch, StereoStreamIsUnchanged) {
  TempDir dir;
  const std::string root = make_stereo_dataset(dir);
  expect_prefetch_changes_nothing(root, stereo_options());
}

TEST(Prefetch, SixteenBitImagesAreScaledInStreamOrder) {
  // A 12-bit camera's 16-bit PNGs, every other frame dark (its largest value fits in 10 bits): each is scaled by the
  // depth of the stream so far, so a dark frame stays dark. Workers decoding ahead used to scale each by its own
  // largest value — a dark frame came out 4x brighter than without prefetching.
  TempDir dir;
  const std::string root = make_stereo_dataset(dir);
  cv::RNG rng(11);
  for (int k = 0; k < kImu / 10; ++k) {
    for (int c = 0; c < 2; ++c) {
      cv::Mat img(48, 64, CV_16UC1);
      rng.fill(img, cv::RNG::UNIFORM, 0, k % 2 == 0 ? 4081 : 766);
      img.at<std::uint16_t>(0, 0) = k % 2 == 0 ? 4080 : 765;
      ASSERT_TRUE(io::codecs::imwrite(image_path(root, c, k), img));
    }
  }
  expect_prefetch_changes_nothing(root, stereo_options());
  Dataset plain = open_dataset(root, stereo_options());
  const Drained d = drain(*plain.source);
  int images = 0;
  for (const Measurement& m : d.items) {
    if (const auto* f = std::get_if<ImageFrame>(&m)) {
      ASSERT_EQ(f->image.type(), CV_8UC1);
      EXPECT_EQ(f->image.at<std::uint8_t>(0, 0), images / 2 % 2 == 0 ? 255 : 48);  // 4080 / 16, 765 / 16 (rounded)
      ++images;
    }
  }
  EXPECT_EQ(images, 2 * kImu / 10);
}

TEST(Prefetch, RealEurocStreamIsUnchanged) {
  const std::string root = test::euroc_dir();
  if (!fs::exists(root)) GTEST_SKIP() << root << " not found (shared datasets absent)";
  DatasetOptions o;    // camera 0 (cam1/data.csv lists two files the folder lacks)
  o.duration_s = 2.0;  // 40 stereo pairs and their IMU: enough, and fast under the sanitizers
  expect_prefetch_changes_nothing(root, o);
}

TEST(Prefetch, WindowAfterSeekIsUnchanged) {
  TempDir dir;
  const std::string root = make_stereo_dataset(dir);
  DatasetOptions o = stereo_options();
  o.start_offset_s = 0.73;  // IndexedSource::seek skips images the workers must not wait for
  o.duration_s = 0.5;
  expect_prefetch_changes_nothing(root, o);
}

TEST(Prefetch, CorruptPngInTheMiddleFailsAfterThePrecedingMeasurementsNamingTheFile) {
  TempDir dir;
  const std::string root = make_stereo_dataset(dir);
  const std::string bad = image_path(root, 1, 17);
  const std::string png = read_text(bad);
  write_text(bad, png.substr(0, png.size() / 2));
  Dataset plain = open_dataset(root, stereo_options());
  const Drained ref = drain(*plain.source);
  ASSERT_NE(ref.error.find(bad), std::string::npos) << ref.error;
  ASSERT_NE(ref.error.find("cannot be decoded"), std::string::npos) << ref.error;
  // Everything before the bad image: 17 stereo pairs, camera 0 of the 18th, the IMU up to its time.
  EXPECT_EQ(std::ranges::count_if(ref.items, [](const auto& m) { return m.index() == 1; }), 2 * 17 + 1);
  expect_prefetch_changes_nothing(root, stereo_options());
  // Skipped under the skip policy: counted the same way.
  expect_prefetch_changes_nothing(root, stereo_options(BadInputPolicy::Skip));
}

TEST(Prefetch, ReaderErrorThroughPrefetchSourceKeepsItsType) {
  TempDir dir;
  const std::string root = make_stereo_dataset(dir);
  // A decoding error: IoError, rethrown as such by the consumer after the measurements before it.
  const std::string bad = image_path(root, 1, 5);
  write_text(bad, "not a png");
  Dataset ds = open_dataset(root, stereo_options());
  PrefetchSource wrapped(std::move(ds.source));
  std::size_t images = 0;
  try {
    while (auto m = wrapped.next()) images += m->index() == 1 ? 1 : 0;
    ADD_FAILURE() << "no error";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
  }
  EXPECT_EQ(images, 2u * 5 + 1);
  EXPECT_FALSE(wrapped.next().has_value()) << "the stream ends after its error";
}

TEST(Prefetch, ConsumerStoppingEarlyShutsDownWithoutHanging) {
  TempDir dir;
  const std::string root = make_stereo_dataset(dir);
  for (int taken : {0, 1, 25, 60}) {
    SCOPED_TRACE(fmt::format("{} measurements taken", taken));
    {
      Dataset ds = open_dataset(root, stereo_options());
      ASSERT_TRUE(ds.source->prefetch(PrefetchOptions{.threads = 3, .depth = 2}));
      for (int i = 0; i < taken; ++i) ASSERT_TRUE(ds.source->next().has_value());
    }  // workers blocked on a full window are told to stop and joined
    {
      Dataset ds = open_dataset(root, stereo_options());
      PrefetchSource wrapped(std::move(ds.source), 1);
      for (int i = 0; i < taken; ++i) ASSERT_TRUE(wrapped.next().has_value());
    }  // the reader blocked on a full queue is told to stop and joined
  }
}

TEST(Prefetch, StartPrefetchPicksTheWayAndZeroIsOff) {
  TempDir dir;
  const std::string root = make_stereo_dataset(dir);
  Dataset ds = open_dataset(root, stereo_options());
  Source* before = ds.source.get();
  EXPECT_EQ(start_prefetch(ds.source, 0), 0);
  EXPECT_EQ(ds.source.get(), before);
  EXPECT_EQ(start_prefetch(ds.source, 2), 2);
  EXPECT_EQ(ds.source.get(), before) << "an IndexedSource decodes ahead itself";
  struct Plain final : Source {
    std::optional<Measurement> next() override { return std::nullopt; }
    const SourceStats& stats() const override { return s; }
    SourceStats s;
  };
  std::unique_ptr<Source> other = std::make_unique<Plain>();
  EXPECT_EQ(start_prefetch(other, 2), 1);
  EXPECT_NE(dynamic_cast<PrefetchSource*>(other.get()), nullptr);
  EXPECT_FALSE(other->next().has_value());
  EXPECT_GE(default_prefetch_threads(), 0);
}

TEST(Prefetch, DefaultLeavesTheFilterItsOwnCore) {
  EXPECT_EQ(default_prefetch_threads(0), 0);  // unknown
  EXPECT_EQ(default_prefetch_threads(1), 0);
  EXPECT_EQ(default_prefetch_threads(2), 1);
  EXPECT_EQ(default_prefetch_threads(3), 2);
  EXPECT_EQ(default_prefetch_threads(5), 4);
  EXPECT_EQ(default_prefetch_threads(64), 4);
}

}  // namespace
}  // namespace rtslam::io
