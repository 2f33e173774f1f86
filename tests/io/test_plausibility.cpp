// Issue 17 item 1, "never silently wrong": values that enter through the readers are checked against physical
// bounds. Each test feeds one class of impossible input and expects a one-line error naming the file (or, with
// bad_input: skip, the item dropped and counted), never a run on the wrong value.
#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*, cv::IMWRITE_*

#include "io_test_util.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/io/calibration.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::io {
namespace {

using test::TempDir;
using test::write_text;

std::vector<ImuSample> imu_at_rest(int n) {
  std::vector<ImuSample> v(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    v[static_cast<std::size_t>(i)].t = 5'000'000LL * i;
    v[static_cast<std::size_t>(i)].accel = Eigen::Vector3d(0.0, 0.0, 9.81);
  }
  return v;
}

std::size_t count_imu(Source& s) {
  std::size_t n = 0;
  while (auto m = s.next()) n += std::holds_alternative<ImuSample>(*m) ? 1 : 0;
  return n;
}

// ------------------------------------------------------------------------------------------------ IMU range

TEST(ImuRange, AnAccelerationNoImuCanMeasureIsAnErrorNamingTheLine) {
  auto imu = imu_at_rest(20);
  imu[7].accel.y() = 1e30;
  StreamCheckOptions o;  // no calibrated full scale: the plausibility limit
  EXPECT_THROW_WITH(IndexedSource(imu, {}, "imu0/data.csv", {}, {}, o), DataError,
                    "accelerometer a_y = 1e+30 m/s² is beyond the sensor's range ±10000");
}

TEST(ImuRange, WithSkipTheSampleIsDroppedCountedAndNeverStreamed) {
  auto imu = imu_at_rest(20);
  imu[7].accel.y() = 1e30;
  imu[9].gyro.x() = -500.0;  // rad/s: beyond any MEMS gyro
  StreamCheckOptions o;
  o.policy = BadInputPolicy::Skip;
  IndexedSource src(imu, {}, "imu0/data.csv", {}, {}, o);
  EXPECT_EQ(count_imu(src), 18u);
  EXPECT_EQ(src.stats().imu_saturated, 2u);
  EXPECT_EQ(src.stats().to_json()["imu_saturated"], 2);
  ASSERT_EQ(src.stats().messages.size(), 2u);
  EXPECT_NE(src.stats().messages[1].find("gyroscope w_x = -500 rad/s"), std::string::npos);
}

TEST(ImuRange, TheCalibratedFullScaleBoundsTheSamplesAndAFullScaleReadingIsKept) {
  const ImuRange r = ImuRange::from_full_scale(5.2, 160.0);
  EXPECT_EQ(r.gyro_rad_s, 5.2);
  EXPECT_EQ(r.accel_m_s2, 160.0);
  ImuSample s;
  s.accel = Eigen::Vector3d(160.0, -160.0, 0.0);  // a saturated sensor reports its full scale: within range
  EXPECT_EQ(imu_range_problem(s, r), "");
  s.accel.x() = 170.0;
  EXPECT_NE(imu_range_problem(s, r).find("beyond the sensor's range ±160 m/s²"), std::string::npos);
  s.accel.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(imu_range_problem(s, r), "");
  // A full scale beyond the plausibility limit is capped by it.
  EXPECT_EQ(ImuRange::from_full_scale(1e9, std::nullopt).gyro_rad_s, ImuRange::kMaxPlausibleGyro);
}

TEST(ImuRange, EurocReaderTakesTheFullScaleFromSensorYaml) {
  TempDir dir;
  const std::string imu_dir = dir / "mav0/imu0";
  write_text(imu_dir + "/sensor.yaml",
             "sensor_type: imu\nrate_hz: 200\ngyroscope_noise_density: 1e-4\ngyroscope_random_walk: 1e-5\n"
             "accelerometer_noise_density: 2e-3\naccelerometer_random_walk: 3e-3\naccelerometer_saturation: 20\n"
             "T_BS: {rows: 4, cols: 4, data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}\n");
  std::string csv = "#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n";
  for (int i = 0; i < 10; ++i) csv += fmt::format("{},0,0,0,0,0,{}\n", 5'000'000LL * i, i == 4 ? 25.0 : 9.81);
  write_text(imu_dir + "/data.csv", csv);
  DatasetOptions o;
  o.cameras = {};
  EXPECT_THROW_WITH(open_dataset("euroc:" + dir.str(), o), DataError,
                    "imu0/data.csv:6: accelerometer a_z = 25 m/s² is beyond the sensor's range ±20 m/s²");
}

// ------------------------------------------------------------------------------------------------ image depth

std::vector<unsigned char> encode(const cv::Mat& m, const std::string& ext) {
  std::vector<unsigned char> buf;
  EXPECT_TRUE(io::codecs::imencode(ext, m, buf));
  return buf;
}

TEST(ImageDepth, SixteenBitPngHoldingEightBitValuesKeepsThem) {
  cv::Mat m(4, 6, CV_16UC1);
  for (int i = 0; i < m.rows * m.cols; ++i) m.at<std::uint16_t>(i) = static_cast<std::uint16_t>(40 * (i % 6) + 10);
  const auto png = encode(m, ".png");
  std::string why;
  int bits = 8;
  const cv::Mat g = decode_grey_image(png.data(), png.size(), &why, &bits);
  ASSERT_FALSE(g.empty()) << why;
  EXPECT_EQ(g.type(), CV_8UC1);
  EXPECT_EQ(bits, 8);
  EXPECT_EQ(g.at<std::uint8_t>(0, 5), 210);  // before: 210 >> 8 = 0, a black image
}

TEST(ImageDepth, TwelveBitValuesAreScaledByTheirSignificantBitsAndTheStreamKeepsItsDepth) {
  cv::Mat m(2, 2, CV_16UC1, cv::Scalar(4095));
  m.at<std::uint16_t>(0, 0) = 1600;
  int bits = 8;
  const cv::Mat g = to_grey8(m, nullptr, &bits);
  EXPECT_EQ(bits, 12);
  EXPECT_EQ(g.at<std::uint8_t>(0, 0), 100);  // 1600 / 16
  EXPECT_EQ(g.at<std::uint8_t>(1, 1), 255);
  // A dark frame of the same camera (max 900 < 1024) is not brightened as if it were 10-bit.
  const cv::Mat dark(2, 2, CV_16UC1, cv::Scalar(800));
  EXPECT_EQ(to_grey8(dark, nullptr, &bits).at<std::uint8_t>(0, 0), 50);
}

TEST(ImageDepth, ColourSixteenBitIsConvertedAndFloatPixelsAreRefused) {
  const cv::Mat bgr(3, 3, CV_16UC3, cv::Scalar(200, 200, 200));
  EXPECT_EQ(to_grey8(bgr).at<std::uint8_t>(1, 1), 200);
  std::string why;
  EXPECT_TRUE(to_grey8(cv::Mat(3, 3, CV_32FC1, cv::Scalar(0.5)), &why).empty());
  EXPECT_NE(why.find("unsupported: floating-point pixels"), std::string::npos) << why;
}

TEST(ImageDepth, AFloatTiffInAFolderIsAnErrorNamingTheFile) {
  // The header check (image_header.hpp) refuses it before decoding; to_grey8 would too.
  TempDir dir;
  io::codecs::imwrite(dir / "0.tiff", cv::Mat(48, 64, CV_32FC1, cv::Scalar(0.5)));
  write_text(dir / "camera.json",
             R"({"model": "pinhole", "width": 64, "height": 48, "fps": 10, "focal_length_x": 50,
                 "focal_length_y": 50, "principal_point_x": 32, "principal_point_y": 24})");
  Dataset ds = open_dataset("images:" + dir.str());
  EXPECT_THROW_WITH(ds.source->next(), IoError, "0.tiff cannot be decoded: it is a TIFF of 1 samples of 32 bits");
}

// ------------------------------------------------------------------------------------------------ calibration

void write_camera_json(const std::string& path, double fx, double cx) {
  write_text(path, fmt::format(R"({{"model": "pinhole", "width": 752, "height": 480, "focal_length_x": {},
    "focal_length_y": 457, "principal_point_x": {}, "principal_point_y": 248}})",
                               fx, cx));
}

TEST(CalibrationPlausibility, AFocalLengthOutsideASaneFieldOfViewNamesFileAndKey) {
  TempDir dir;
  write_camera_json(dir / "huge.json", 1e300, 367);
  EXPECT_THROW_WITH(load_monoslam_camera(dir / "huge.json"), ConfigError,
                    "huge.json: fx = 1e+300 must be in [16.42, 8.617e+04] px for a field of view in [0.5, 175] deg");
  write_camera_json(dir / "tiny.json", 1e-3, 367);
  EXPECT_THROW_WITH(load_monoslam_camera(dir / "tiny.json"), ConfigError, "tiny.json: fx = 0.001 must be in");
  write_camera_json(dir / "ok.json", 458, 367);
  EXPECT_NO_THROW(load_monoslam_camera(dir / "ok.json"));
}

TEST(CalibrationPlausibility, APrincipalPointOutsideTheImageNamesFileAndKey) {
  TempDir dir;
  write_camera_json(dir / "c.json", 458, -5000);
  EXPECT_THROW_WITH(load_monoslam_camera(dir / "c.json"), ConfigError,
                    "c.json: cx = -5000 must be inside the image, in [0, 752] px");
  write_text(dir / "rig.yaml", "cameras:\n  - {width: 752, height: 480, intrinsics: [458, 457, 367, 900]}\n");
  EXPECT_THROW_WITH(load_rig_yaml(dir / "rig.yaml"), ConfigError, "cameras[0]: cy = 900 must be inside the image");
}

TEST(CalibrationPlausibility, ImuNoiseAndSaturationHaveUpperBounds) {
  TempDir dir;
  const std::string imu =
      "sensor_type: imu\nrate_hz: 200\ngyroscope_random_walk: 1e-5\naccelerometer_noise_density: 2e-3\n"
      "accelerometer_random_walk: 3e-3\nT_BS: {rows: 4, cols: 4, data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, "
      "1]}\n";
  write_text(dir / "a.yaml", imu + "gyroscope_noise_density: 1e6\n");
  EXPECT_THROW_WITH(load_euroc_imu(dir / "a.yaml"), ConfigError, "gyroscope_noise_density = 1000000 must be < 10");
  write_text(dir / "b.yaml", imu + "gyroscope_noise_density: 1e-4\ngyroscope_saturation: 1e9\n");
  EXPECT_THROW_WITH(load_euroc_imu(dir / "b.yaml"), ConfigError, "gyroscope_saturation = 1000000000 must be <= 200");
}

// ------------------------------------------------------------------------------------------------ times, options

TEST(DatasetOptionsBounds, ARateWhoseImageTimesOverflowIsRefusedNamingTheOption) {
  DatasetOptions o;
  o.rate_hz = 1e-300;  // image i at i * 1e309 ns: beyond int64
  EXPECT_THROW_WITH(o.validate(), ConfigError, "rate_hz (--rate) = 1e-300 must be 0 (from the data) or in");
  o.rate_hz = 0.0;
  o.max_imu_dropout = -1;
  EXPECT_THROW_WITH(o.validate(), ConfigError, "max_imu_dropout (--max-imu-dropout) = -1 must be in [0, 1000000]");
  o.max_imu_dropout = 3;
  o.cameras = {99};
  EXPECT_THROW_WITH(o.validate(), ConfigError, "cameras[] = 99 must be in [0, 15]");
}

TEST(DatasetOptionsBounds, AWindowBeyondTheTimeRangeIsEmptyNotAnOverflow) {
  auto imu = imu_at_rest(5);
  for (auto& s : imu) s.t += std::numeric_limits<TimeNs>::max() - 1'000'000'000;  // near the end of int64
  StreamCheckOptions o;
  WindowSource w(std::make_unique<IndexedSource>(imu, std::vector<int>{}, "", std::vector<ImageEntry>{},
                                                 std::vector<cv::Size>{}, o),
                 9e9, 1e9);
  EXPECT_FALSE(w.next().has_value());
  WindowSource whole(std::make_unique<IndexedSource>(imu, std::vector<int>{}, "", std::vector<ImageEntry>{},
                                                     std::vector<cv::Size>{}, o),
                     0.0, 5e9);  // the window's end saturates at the int64 end: every sample
  std::size_t n = 0;
  while (whole.next()) ++n;
  EXPECT_EQ(n, 5u);
}

}  // namespace
}  // namespace rtslam::io
