// The broken-dataset suite: small EuRoC folders written by EurocWriter, then broken one way each. With the default
// policy each gives a one-line error naming the file and the problem; with the skip policy the stream goes on and
// the problem is counted. Never a crash (this suite also runs under ASan/UBSan).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*, cv::IMWRITE_*

#include "io_test_util.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/writers.hpp"

namespace rtslam::io {
namespace {

namespace fs = std::filesystem;
using test::read_text;
using test::TempDir;
using test::write_text;

constexpr TimeNs kT0 = 1'000'000'000'000;
constexpr int kImu = 200;    // 1 s at 200 Hz
constexpr int kImages = 10;  // every 20th IMU time

/// A valid small EuRoC folder: one 32x24 camera, 200 IMU samples, 10 images.
std::string make_dataset(const TempDir& dir) {
  Rig rig;
  CameraCalibration cam;
  cam.name = "cam0";
  cam.width = 32;
  cam.height = 24;
  cam.rate_hz = 10;
  cam.fx = cam.fy = 30;
  cam.cx = 16;
  cam.cy = 12;
  cam.distortion = DistortionModel::RadTan;
  cam.distortion_coeffs = {-0.28, 0.07, 2e-4, 2e-5};
  rig.cameras.push_back(cam);
  rig.imu = test::small_imu();
  const std::string root = dir / "seq";
  EurocWriter w(root, rig);
  for (int i = 0; i < kImu; ++i) {
    ImuSample s;
    s.t = kT0 + i * 5'000'000;
    s.gyro = Eigen::Vector3d(0.01 * i, 0.0, -0.02);
    s.accel = Eigen::Vector3d(9.81, 0.1, 0.0);
    w.add_imu(s);
    if (i % 20 == 0) w.add_image(0, s.t, cv::Mat(24, 32, CV_8UC1, cv::Scalar(i)));
  }
  w.close();
  return root;
}

std::string image_path(const std::string& root, int k) {
  return fmt::format("{}/mav0/cam0/data/{}.png", root, kT0 + k * 20 * 5'000'000);
}

std::vector<std::string> lines_of(const std::string& path) {
  std::vector<std::string> lines;
  std::ifstream in(path);
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  return lines;
}

void write_lines(const std::string& path, const std::vector<std::string>& lines) {
  std::ofstream out(path);
  for (const auto& l : lines) out << l << '\n';
}

struct Result {
  SourceStats stats;
};

/// Opens and drains the dataset with the given policy.
Result run(const std::string& root, BadInputPolicy policy) {
  DatasetOptions o;
  o.bad_input = policy;
  Dataset ds = open_dataset(root, o);
  while (ds.source->next()) {
  }
  return {ds.source->stats()};
}

/// Under Error: throws `E` whose one-line message contains every needle. Returns the message.
template <class E>
std::string expect_error(const std::string& root, std::initializer_list<std::string> needles) {
  try {
    run(root, BadInputPolicy::Error);
    ADD_FAILURE() << "no error";
  } catch (const E& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "not one line: " << msg;
    for (const auto& n : needles) EXPECT_NE(msg.find(n), std::string::npos) << "'" << n << "' not in: " << msg;
    return msg;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
  }
  return {};
}

TEST(BadInput, ValidDatasetHasNoProblems) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  const Result r = run(root, BadInputPolicy::Error);
  EXPECT_EQ(r.stats.images, static_cast<size_t>(kImages));
  EXPECT_EQ(r.stats.imu_samples, static_cast<size_t>(kImu));
  EXPECT_EQ(r.stats.problems(), 0u);
}

TEST(BadInput, MissingImage) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  fs::remove(image_path(root, 5));
  expect_error<IoError>(root, {"cam0/data.csv:7:", image_path(root, 5), "not found"});
  const Result r = run(root, BadInputPolicy::Skip);
  EXPECT_EQ(r.stats.missing_images, 1u);
  EXPECT_EQ(r.stats.images, static_cast<size_t>(kImages - 1));
  EXPECT_EQ(r.stats.imu_samples, static_cast<size_t>(kImu));
}

TEST(BadInput, TruncatedPng) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string png = read_text(image_path(root, 3));
  write_text(image_path(root, 3), png.substr(0, png.size() / 2));
  // Refused before OpenCV's decoder, whose libpng printed its own line first (review 27 Nov).
  expect_error<IoError>(root, {"cam0/data.csv:5:", image_path(root, 3),
                               "cannot be decoded: truncated PNG (its chunks end before IEND)"});
  const Result r = run(root, BadInputPolicy::Skip);
  EXPECT_EQ(r.stats.undecodable_images, 1u);
  EXPECT_EQ(r.stats.images, static_cast<size_t>(kImages - 1));
  EXPECT_NE(r.stats.summary().find("1 undecodable image"), std::string::npos) << r.stats.summary();
}

TEST(BadInput, NotAnImageAtAll) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  write_text(image_path(root, 0), "this is text, not a PNG");
  expect_error<IoError>(root, {"cam0/data.csv:2:", "cannot be decoded"});
}

TEST(BadInput, UnorderedImuTimestamps) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string csv = root + "/mav0/imu0/data.csv";
  auto lines = lines_of(csv);
  std::swap(lines[50], lines[51]);  // samples 49 and 50 (line 1 is the header)
  write_lines(csv, lines);
  expect_error<DataError>(root, {"imu0/data.csv:52:", "goes backwards"});
  const Result r = run(root, BadInputPolicy::Skip);
  EXPECT_EQ(r.stats.backwards_timestamps, 1u);
  EXPECT_EQ(r.stats.imu_samples, static_cast<size_t>(kImu - 1));
}

TEST(BadInput, DuplicateImageTimestamp) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string csv = root + "/mav0/cam0/data.csv";
  auto lines = lines_of(csv);
  lines.insert(lines.begin() + 4, lines[3]);
  write_lines(csv, lines);
  expect_error<DataError>(root, {"cam0/data.csv:5:", "duplicate image timestamp"});
  const Result r = run(root, BadInputPolicy::Skip);
  EXPECT_EQ(r.stats.duplicate_timestamps, 1u);
  EXPECT_EQ(r.stats.images, static_cast<size_t>(kImages));
}

TEST(BadInput, ImageTimestampJumpingYearsAhead) {
  // Review 27 Nov: a last image stamped 1e8 s late was predicted to and ended the run 300 km away, exit 0.
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string csv = root + "/mav0/cam0/data.csv";
  auto lines = lines_of(csv);
  const std::string last = lines.back();
  const std::string file = last.substr(last.find(','));
  lines.back() = fmt::format("{}{}", kT0 + 100'000'000'000'000'000LL, file);
  write_lines(csv, lines);
  expect_error<DataError>(root, {"cam0/data.csv:" + std::to_string(lines.size()) + ":", "corrupt timestamp"});
  const Result r = run(root, BadInputPolicy::Skip);
  EXPECT_EQ(r.stats.timestamp_jumps, 1u);
  EXPECT_EQ(r.stats.images, static_cast<size_t>(kImages - 1));
}

TEST(BadInput, NanInImu) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string csv = root + "/mav0/imu0/data.csv";
  auto lines = lines_of(csv);
  lines[11] = fmt::format("{},nan,0,0,9.81,0,0", kT0 + 10 * 5'000'000);
  write_lines(csv, lines);
  expect_error<DataError>(root, {"imu0/data.csv:12:", "non-finite"});
  const Result r = run(root, BadInputPolicy::Skip);
  EXPECT_EQ(r.stats.non_finite, 1u);
  EXPECT_EQ(r.stats.imu_samples, static_cast<size_t>(kImu - 1));
}

TEST(BadInput, ImuValueBeyondDoubleRange) {
  // Review 27 Nov: 1e400 was read as 0 and the run went on.
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string csv = root + "/mav0/imu0/data.csv";
  auto lines = lines_of(csv);
  lines[11] = fmt::format("{},0,0,0,9.81,0,1e400", kT0 + 10 * 5'000'000);
  write_lines(csv, lines);
  expect_error<IoError>(root, {"imu0/data.csv:12:", "1e400"});
  const Result r = run(root, BadInputPolicy::Skip);
  EXPECT_EQ(r.stats.malformed_lines, 1u);
  EXPECT_EQ(r.stats.imu_samples, static_cast<size_t>(kImu - 1));
}

TEST(BadInput, ImuDropoutLongerThanThreeSamples) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string csv = root + "/mav0/imu0/data.csv";
  auto lines = lines_of(csv);
  lines.erase(lines.begin() + 101, lines.begin() + 105);  // 4 samples missing: more than 3
  write_lines(csv, lines);
  expect_error<DataError>(root, {"imu0/data.csv:102:", "IMU gap of 0.025 s", "~4 samples missing"});
  const Result r = run(root, BadInputPolicy::Skip);
  EXPECT_EQ(r.stats.imu_gaps, 1u);
  EXPECT_EQ(r.stats.imu_samples, static_cast<size_t>(kImu - 4));  // a gap drops nothing
  // Exactly 3 missing samples are tolerated.
  TempDir dir2;
  const std::string root2 = make_dataset(dir2);
  const std::string csv2 = root2 + "/mav0/imu0/data.csv";
  auto l2 = lines_of(csv2);
  l2.erase(l2.begin() + 101, l2.begin() + 104);
  write_lines(csv2, l2);
  EXPECT_EQ(run(root2, BadInputPolicy::Error).stats.imu_samples, static_cast<size_t>(kImu - 3));
}

TEST(BadInput, MalformedCsvLine) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string csv = root + "/mav0/imu0/data.csv";
  auto lines = lines_of(csv);
  lines[30] = "1000145000000,0.29,0,-0.02,9.81";  // 5 columns
  write_lines(csv, lines);
  expect_error<IoError>(root, {"imu0/data.csv:31:", "expected 7 numbers"});
  const Result r = run(root, BadInputPolicy::Skip);
  EXPECT_EQ(r.stats.malformed_lines, 1u);
  EXPECT_EQ(r.stats.imu_samples, static_cast<size_t>(kImu - 1));
}

TEST(BadInput, WrongImageSize) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  io::codecs::imwrite(image_path(root, 2), cv::Mat(16, 16, CV_8UC1, cv::Scalar(1)));
  expect_error<DataError>(root, {"cam0/data.csv:4:", "is 16x16, the calibration of camera 0 says 32x24"});
  EXPECT_EQ(run(root, BadInputPolicy::Skip).stats.wrong_size_images, 1u);
}

TEST(BadInput, MalformedSensorYaml) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string yaml = root + "/mav0/cam0/sensor.yaml";
  write_text(yaml, read_text(yaml) + "intrinsics: [1, 2\n");
  expect_error<ConfigError>(root, {yaml, "malformed YAML at line"});
}

TEST(BadInput, CameraListWithNoImage) {
  // Review 27 Nov: the error came from the pipeline ("dataset 'x' has no image ..."), without the file.
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string csv = root + "/mav0/cam0/data.csv";
  write_lines(csv, {"#timestamp [ns],filename"});
  expect_error<DataError>(root, {csv, "lists no image"});
}

TEST(BadInput, SensorYamlKeyTwice) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string yaml = root + "/mav0/cam0/sensor.yaml";
  write_text(yaml, read_text(yaml) + "intrinsics: [1, 2, 3, 4]\n");
  expect_error<ConfigError>(root, {yaml, "key 'intrinsics' given twice"});
}

TEST(BadInput, UnknownDistortionModel) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string yaml = root + "/mav0/cam0/sensor.yaml";
  std::string text = read_text(yaml);
  text.replace(text.find("radial-tangential"), 17, "fov");
  write_text(yaml, text);
  expect_error<ConfigError>(root, {yaml, "unknown distortion model 'fov'"});
}

TEST(BadInput, NonOrthonormalTBS) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  const std::string yaml = root + "/mav0/cam0/sensor.yaml";
  std::string text = read_text(yaml);
  text.replace(text.find("data: [1,"), 9, "data: [1.2,");
  write_text(yaml, text);
  expect_error<ConfigError>(root, {yaml, "'T_BS' rotation is not orthonormal"});
}

TEST(BadInput, MissingFiles) {
  TempDir dir;
  const std::string root = make_dataset(dir);
  fs::remove(root + "/mav0/imu0/sensor.yaml");
  expect_error<IoError>(root, {"imu0/sensor.yaml: file not found"});
  fs::remove(root + "/mav0/cam0/data.csv");
  TempDir dir2;
  const std::string root2 = make_dataset(dir2);
  fs::remove(root2 + "/mav0/cam0/data.csv");
  expect_error<IoError>(root2, {"cam0/data.csv: file not found"});
}

TEST(BadInput, PolicyNamesAndStatsJson) {
  EXPECT_EQ(bad_input_policy_from_string("skip"), BadInputPolicy::Skip);
  EXPECT_EQ(bad_input_policy_from_string("error"), BadInputPolicy::Error);
  EXPECT_THROW_WITH(bad_input_policy_from_string("ignore", "run.bad_input"), ConfigError,
                    "run.bad_input = 'ignore' must be 'error' or 'skip'");
  TempDir dir;
  const std::string root = make_dataset(dir);
  fs::remove(image_path(root, 1));
  const Result r = run(root, BadInputPolicy::Skip);
  const nlohmann::json j = r.stats.to_json();
  EXPECT_EQ(j["missing_images"], 1);
  EXPECT_EQ(j["images"], kImages - 1);
  ASSERT_EQ(j["messages"].size(), 1u);
  EXPECT_NE(j["messages"][0].get<std::string>().find(image_path(root, 1)), std::string::npos);
}

}  // namespace
}  // namespace rtslam::io
