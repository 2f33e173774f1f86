// Inputs found by the fuzz targets (fuzz/, docs/testing.md "Fuzzing") and by the review of the parsers that came
// with them, each reduced to its cause. Every one must end in a typed error that names the file (or, for images,
// an undecodable-image result saying why) — never another exception type, a crash, a sanitizer report or a huge
// allocation. The raw fuzzer inputs are kept in fuzz/corpus/<target>/finding-* and replayed by the fuzz build.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*, cv::IMWRITE_*

#include "io_test_util.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/io/calibration.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/image_header.hpp"
#include "rtslam/io/source.hpp"
#include "rtslam/io/text.hpp"
#include "rtslam/io/trajectory_io.hpp"

namespace rtslam::io {
namespace {

namespace fs = std::filesystem;
using test::TempDir;
using test::write_text;

const char* kRig = "cameras:\n  - {width: 8, height: 6, intrinsics: [10, 10, 4, 3]}\n";

// ------------------------------------------------------------------------------------------------ calibration

TEST(FuzzRegressions, KalibrCameraEntryThatIsNotAMapping) {
  // fuzz_calib_kalibr: yaml-cpp's BadSubscript escaped load_kalibr ("operator[] call on a scalar").
  TempDir dir;
  write_text(dir / "camchain.yaml", "cam0: pinhole\n");
  EXPECT_THROW_WITH(load_kalibr(dir / "camchain.yaml"), ConfigError, dir / "camchain.yaml/cam0: expected a mapping");
  write_text(dir / "imu.yaml", "imu0: [1, 2]\n");
  EXPECT_THROW_WITH(load_kalibr_imu(dir / "imu.yaml"), ConfigError, dir / "imu.yaml/imu0: expected a mapping");
}

TEST(FuzzRegressions, SensorTypeThatIsNotAString) {
  TempDir dir;
  write_text(dir / "sensor.yaml", "sensor_type: {camera: 1}\n");
  EXPECT_THROW_WITH(load_euroc_camera(dir / "sensor.yaml"), ConfigError, "cannot read 'sensor_type'");
  EXPECT_THROW_WITH(load_euroc_imu(dir / "sensor.yaml"), ConfigError, "cannot read 'sensor_type'");
  EXPECT_THROW_WITH(load_calibration(dir / "sensor.yaml"), ConfigError, "cannot read 'sensor_type'");
}

TEST(FuzzRegressions, ResolutionThatIsNotAnImageSide) {
  // fuzz_calib_kalibr: 1.70606e+11 cast to int (undefined behaviour, reported by UBSan).
  TempDir dir;
  const std::string head = "cam0:\n  intrinsics: [458, 457, 367, 248]\n  distortion_model: none\n  resolution: ";
  write_text(dir / "a.yaml", head + "[1.70606e+11, 480]\n");
  EXPECT_THROW_WITH(load_kalibr(dir / "a.yaml"), ConfigError, "resolution[0] = 170606000000 must be an integer in");
  write_text(dir / "b.yaml", head + "[752.5, 480]\n");
  EXPECT_THROW_WITH(load_kalibr(dir / "b.yaml"), ConfigError, "resolution[0] = 752.5 must be an integer in");
  write_text(dir / "camera.json", R"({"width": 1e10, "height": 240, "focal_length_x": 195, "focal_length_y": 195,
    "principal_point_x": 162, "principal_point_y": 125, "model": "pinhole"})");
  EXPECT_THROW_WITH(load_monoslam_camera(dir / "camera.json"), ConfigError, "width = 10000000000 must be");
  write_text(dir / "rig.yaml", "cameras:\n  - {width: 100000, height: 100000, intrinsics: [10, 10, 4, 3]}\n");
  EXPECT_THROW_WITH(load_rig_yaml(dir / "rig.yaml"), ConfigError, "width = 100000 must be in [1, 65536]");
  write_text(dir / "rig2.yaml", "cameras:\n  - {width: 60000, height: 60000, intrinsics: [10, 10, 4, 3]}\n");
  EXPECT_THROW_WITH(load_rig_yaml(dir / "rig2.yaml"), ConfigError, "width x height = 3600000000 must be <=");
}

TEST(FuzzRegressions, ImuSaturationAndNoiseMustBePositiveAndFinite) {
  // fuzz_calib_euroc: a negative accelerometer_saturation was accepted.
  TempDir dir;
  const std::string imu =
      "sensor_type: imu\nrate_hz: 200\ngyroscope_noise_density: 1e-4\ngyroscope_random_walk: 1e-5\n"
      "accelerometer_noise_density: 2e-3\naccelerometer_random_walk: 3e-3\n"
      "T_BS: {rows: 4, cols: 4, data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}\n";
  write_text(dir / "a.yaml", imu + "accelerometer_saturation: -160\n");
  EXPECT_THROW_WITH(load_euroc_imu(dir / "a.yaml"), ConfigError, "accelerometer_saturation = -160 must be > 0, finite");
  write_text(dir / "b.yaml", imu + "gyroscope_saturation: .nan\n");
  EXPECT_THROW_WITH(load_euroc_imu(dir / "b.yaml"), ConfigError, "gyroscope_saturation = nan must be > 0, finite");
  std::string inf = imu;
  inf.replace(inf.find("rate_hz: 200"), 12, "rate_hz: .inf");
  write_text(dir / "c.yaml", inf);
  EXPECT_THROW_WITH(load_euroc_imu(dir / "c.yaml"), ConfigError, "rate_hz = inf must be > 0, finite");
}

TEST(FuzzRegressions, RigYamlNonFiniteNumbers) {
  // Review: YamlMap::get_matrix took .nan, and a NaN in the last row of T_RS passed the [0 0 0 1] check.
  TempDir dir;
  write_text(dir / "a.yaml",
             "cameras:\n  - {width: 8, height: 6, intrinsics: [10, 10, 4, 3], distortion_model: radtan,\n"
             "     distortion_coeffs: [.nan, 0, 0, 0]}\n");
  EXPECT_THROW_WITH(load_rig_yaml(dir / "a.yaml"), ConfigError, "'distortion_coeffs' contains a non-finite number");
  write_text(dir / "b.yaml",
             "cameras:\n  - {width: 8, height: 6, intrinsics: [10, 10, 4, 3],\n"
             "     T_RS: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, .nan, 1]}\n");
  EXPECT_THROW_WITH(load_rig_yaml(dir / "b.yaml"), ConfigError, "'T_RS' contains a non-finite number");
  write_text(dir / "c.yaml", std::string(kRig) + "t_d: .nan\n");
  EXPECT_THROW_WITH(load_rig_yaml(dir / "c.yaml"), ConfigError, "t_d = nan must be finite");
  write_text(dir / "d.yaml", "cam0:\n  intrinsics: [458, 457, 367, 248]\n  distortion_model: none\n"
                             "  resolution: [752, 480]\n  timeshift_cam_imu: 1e300\n");
  EXPECT_THROW_WITH(load_kalibr(dir / "d.yaml"), ConfigError, "timeshift_cam_imu = 1e+300 must be finite");
}

TEST(FuzzRegressions, RigYamlNamesRoundTrip) {
  // Review (the fuzz_calib_rig round trip): names were written unquoted, so "a: b", "#c" or "" did not read back.
  TempDir dir;
  for (const std::string name : {"", "a: b", "#c", "null", "~", "[x]", "quote\" back\\slash", "tab\tnew\nline",
                                 "caméra"}) {
    Rig rig;
    CameraCalibration cam;
    cam.name = name;
    cam.width = 8;
    cam.height = 6;
    cam.fx = cam.fy = 10;
    rig.cameras.push_back(cam);
    ImuCalibration imu;
    imu.name = name;
    imu.rate_hz = 200;
    imu.gyro_noise_density = imu.accel_noise_density = 1e-3;
    rig.imu = imu;
    write_rig_yaml(dir / "rig.yaml", rig);
    const Rig back = load_rig_yaml(dir / "rig.yaml");
    ASSERT_EQ(back.cameras.size(), 1u);
    EXPECT_EQ(back.cameras[0].name, name);
    ASSERT_TRUE(back.imu.has_value());
    EXPECT_EQ(back.imu->name, name);
  }
}

TEST(FuzzRegressions, KittiCalibNonFiniteNumbers) {
  // Review: parse_double accepts "nan" and "inf"; a NaN fx passed the `fx <= 0` check.
  TempDir dir;
  write_text(dir / "calib.txt", "P0: nan 0 4 0 0 10 3 0 0 0 1 0\n");
  EXPECT_THROW_WITH(load_kitti_calib(dir / "calib.txt", 0), ConfigError, "'P0:' contains a non-finite number");
  write_text(dir / "calib.txt", "P0: 10 0 4 inf 0 10 3 0 0 0 1 0\n");
  EXPECT_THROW_WITH(load_kitti_calib(dir / "calib.txt", 0), ConfigError, "'P0:' contains a non-finite number");
  write_text(dir / "calib.txt", "P0: 1e-320 0 4 -1e10 0 10 3 0 0 0 1 0\n");
  EXPECT_THROW_WITH(load_kitti_calib(dir / "calib.txt", 0), ConfigError, "non-finite position");
}

TEST(FuzzRegressions, KittiRotationsAreUnitQuaternionsBothWays) {
  // Review of the fuzz_trajectory round trip: a KITTI rotation off by up to 1e-3 became a non-unit quaternion,
  // and write_kitti wrote toRotationMatrix() of whatever quaternion it had: from a TUM pose 1e-2 off unit norm,
  // a matrix read_kitti rejects.
  TempDir dir;
  write_text(dir / "scaled.txt", "0.8779335949151289 -0.47961730881964465 0 1 0.47961730881964465 "
                                 "0.8779335949151289 0 2 0 0 1.0004 3\n");
  const Trajectory kitti = read_trajectory(dir / "scaled.txt", TrajectoryFormat::Kitti);
  ASSERT_EQ(kitti.poses.size(), 1u);
  EXPECT_NEAR(kitti.poses[0].q_WR.norm(), 1.0, 1e-15);
  const Eigen::Quaterniond q_z(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  EXPECT_LT(kitti.poses[0].q_WR.angularDistance(q_z), 1e-3);  // the matrix is a rotation only to 1e-3
  write_text(dir / "tum.txt", "1 0 0 0 0.3 0.1 0.2 0.935\n");  // norm 1.0059
  const Trajectory tum = read_trajectory(dir / "tum.txt", TrajectoryFormat::Tum);
  write_kitti(dir / "00.txt", tum);
  const Trajectory back = read_trajectory(dir / "00.txt", TrajectoryFormat::Kitti);
  ASSERT_EQ(back.poses.size(), 1u);
  EXPECT_LT(back.poses[0].q_WR.angularDistance(tum.poses[0].q_WR.normalized()), 1e-12);
}

// ------------------------------------------------------------------------------------------------ lists and times

TEST(FuzzRegressions, SecondsBeyondInt64Nanoseconds) {
  // Review, reproduced with fuzz_dataset_lists: "9999999999" (10 digits) overflowed int64 ns (UBSan).
  TimeNs t = 0;
  EXPECT_FALSE(parse_seconds("9999999999", t));
  EXPECT_FALSE(parse_seconds("-9223372037", t));
  EXPECT_FALSE(parse_seconds("9223372036.854775808", t));
  ASSERT_TRUE(parse_seconds("9223372036.854775807", t));
  EXPECT_EQ(t, std::numeric_limits<TimeNs>::max());
  ASSERT_TRUE(parse_seconds("-9223372036.854775807", t));
  EXPECT_EQ(t, -std::numeric_limits<TimeNs>::max());
  TempDir dir;
  write_text(dir / "calibration.yaml", kRig);
  fs::create_directories(dir / "rgb");
  io::codecs::imwrite(dir / "rgb/1.png", cv::Mat(6, 8, CV_8UC1, cv::Scalar(1)));
  write_text(dir / "rgb.txt", "9999999999 rgb/1.png\n");
  EXPECT_THROW_WITH(open_dataset("tum:" + dir.str()), IoError, "rgb.txt:1: expected 'timestamp[s] filename'");
}

TEST(FuzzRegressions, ImuTimestampsFarApart) {
  // Review, reproduced with fuzz_dataset_lists: t - t_prev overflowed int64 (UBSan), with and without a rate.
  const TimeNs lo = std::numeric_limits<TimeNs>::min() + 1;
  const TimeNs hi = std::numeric_limits<TimeNs>::max();
  for (const double rate : {200.0, 0.0}) {  // 0: the period is the median interval (5 ms here)
    std::vector<ImuSample> imu(5);
    for (int i = 0; i < 4; ++i) imu[static_cast<size_t>(i)].t = lo + i * 5'000'000;
    imu[4].t = hi;
    StreamCheckOptions o;
    o.imu_rate_hz = rate;
    EXPECT_THROW_WITH((void)IndexedSource(imu, {}, "imu0/data.csv", {}, {}, o), DataError,
                      "IMU gap of 18446744073.695 s");
    o.policy = BadInputPolicy::Skip;
    IndexedSource src(imu, {}, "imu0/data.csv", {}, {}, o);
    EXPECT_EQ(src.stats().imu_gaps, 1u);
  }
}

TEST(FuzzRegressions, KittiTimesSpanningMoreThanInt64) {
  // Review, reproduced with fuzz_dataset_lists: the nominal rate divided by times.back() - times.front(), which
  // overflowed. Such a span gives no rate (0 = unknown).
  TempDir dir;
  const std::string seq = dir / "sequences/00";
  fs::create_directories(seq + "/image_0");
  io::codecs::imwrite(seq + "/image_0/000000.png", cv::Mat(6, 8, CV_8UC1, cv::Scalar(1)));
  io::codecs::imwrite(seq + "/image_0/000001.png", cv::Mat(6, 8, CV_8UC1, cv::Scalar(2)));
  write_text(seq + "/calib.txt", "P0: 10 0 4 0 0 10 3 0 0 0 1 0\n");
  write_text(seq + "/times.txt", "-9000000000.5\n9000000000.5\n");
  // Such a jump is a corrupt timestamp (io::kMaxImageJumpS): an error, or skipped with the span's rate unknown.
  EXPECT_THROW_WITH(open_dataset("kitti:" + seq), DataError, "a corrupt timestamp");
  DatasetOptions skip;
  skip.bad_input = BadInputPolicy::Skip;
  const Dataset ds = open_dataset("kitti:" + seq, skip);
  EXPECT_EQ(ds.rig.cameras[0].rate_hz, 0.0);
  EXPECT_EQ(ds.source->stats().timestamp_jumps, 1u);
  write_text(seq + "/times.txt", "0\n0.1\n");
  EXPECT_NEAR(open_dataset("kitti:" + seq).rig.cameras[0].rate_hz, 10.0, 1e-9);
  // Review: a calibration file without a camera was std::out_of_range.
  write_text(dir / "imu.yaml", "accelerometer_noise_density: 2e-3\naccelerometer_random_walk: 3e-3\n"
                               "gyroscope_noise_density: 1e-4\ngyroscope_random_walk: 1e-5\nupdate_rate: 200\n");
  DatasetOptions o;
  o.calibration = dir / "imu.yaml";
  EXPECT_THROW_WITH(open_dataset("kitti:" + seq, o), ConfigError, dir / "imu.yaml: calibration has no camera");
}

// ------------------------------------------------------------------------------------------------ images

std::vector<unsigned char> bytes_of(const std::string& s) { return {s.begin(), s.end()}; }

std::string decode_problem(const std::vector<unsigned char>& b) {
  std::string why;
  const cv::Mat img = decode_grey_image(b.data(), b.size(), &why);
  EXPECT_TRUE(img.empty());
  return why;
}

/// A little-endian TIFF: 8-bit grey, `width` x `height`, `rows_per_strip` rows a strip, one strip of 8 bytes; with
/// a TileWidth tag too when `tile_width` is not 0, of TIFF type `tile_type` (3 SHORT, 4 LONG, 8 SSHORT...).
std::vector<unsigned char> tiff(std::uint32_t width, std::uint32_t height, std::uint32_t rows_per_strip,
                                std::uint32_t tile_width = 0, std::uint32_t tile_type = 4) {
  std::vector<unsigned char> b = {'I', 'I', 42, 0, 8, 0, 0, 0};
  const auto u16 = [&b](std::uint32_t v) {
    b.push_back(v & 0xFF);
    b.push_back((v >> 8) & 0xFF);
  };
  const auto u32 = [&](std::uint32_t v) {
    u16(v & 0xFFFF);
    u16(v >> 16);
  };
  const std::uint32_t n = tile_width ? 9 : 8;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> entries = {
      {256, width}, {257, height}, {258, 8}, {259, 1}, {262, 1}, {273, 8 + 2 + n * 12 + 4}, {277, 1},
      {278, rows_per_strip}};
  if (tile_width) entries.emplace_back(322, tile_width);
  u16(static_cast<std::uint32_t>(entries.size()));
  for (const auto& [tag, value] : entries) {
    const std::uint32_t type = tag == 322 ? tile_type : 4;  // LONG but for the TileWidth
    u16(tag);
    u16(type);
    u32(1);
    if (type == 4 || type == 9) {
      u32(value);
    } else if (type == 3 || type == 8) {
      u16(value);  // inline, left-justified in the 4 bytes
      u16(0);
    } else {
      u32(value & 0xFF);  // BYTE / SBYTE: the first byte
    }
  }
  u32(0);  // no next directory
  for (int i = 0; i < 8; ++i) b.push_back(static_cast<unsigned char>(i * 30));
  return b;
}

TEST(FuzzRegressions, ImageHeaderBeyondOpenCvLimitsIsUndecodable) {
  // fuzz_image_decode: OpenCV's imdecode threw cv::Exception (not an empty Mat) for a PBM of height 16455555.
  EXPECT_NE(decode_problem(bytes_of("P4 2\n16455555\xc8\xfc" "5\xca\xca\xd1\xca\xca\xca\xca\xcaN")).find(
                "cannot be decoded: it declares 2x16455555 px"),
            std::string::npos);
}

TEST(FuzzRegressions, HugeDeclaredImagesAreRefusedBeforeDecoding) {
  // fuzz_image_decode (out-of-memory, -malloc_limit_mb=512): a 20-byte PBM stating 883888x888 px (785 MB), a TIFF
  // whose 65304-row strips made OpenCV allocate 3.9 GB, and a DICOM file GDCM read as 3.5 GB.
  EXPECT_NE(decode_problem(bytes_of("P1\n883888 888\n")).find("declares 883888x888 px, more than"),
            std::string::npos);
  EXPECT_NE(decode_problem(tiff(14880, 247, 65304)).find("strips or tiles hold 971723520 px"), std::string::npos);
  std::vector<unsigned char> dicom(132, 0);
  dicom[128] = 'D';
  dicom[129] = 'I';
  dicom[130] = 'C';
  dicom[131] = 'M';
  EXPECT_NE(decode_problem(dicom).find("not a PNG, PNM, JPEG, BMP or TIFF image"), std::string::npos);
  EXPECT_NE(decode_problem(bytes_of("v/1\x01....")).find("not a PNG"), std::string::npos);  // OpenEXR
  // fuzz_image_decode, 10-minute run: "P403..." passed for a PNM here, but OpenCV wants white space after "P4", so
  // it went on to GDCM, which read the "DICM" further on as a 1.6 GB element.
  std::vector<unsigned char> p4_dicom = bytes_of("P403\n4 2\n");
  p4_dicom.resize(132, 0);
  std::copy_n("DICM", 4, p4_dicom.begin() + 128);
  EXPECT_NE(decode_problem(p4_dicom).find("not a PNG, PNM"), std::string::npos);
  // fuzz_image_decode, 10-minute run: OpenCV consumes the byte after a number, so the '#' after the width starts
  // no comment and this 16-byte PBM is 33313x23332 px (777 MB), not the 33313x3 the header check read.
  EXPECT_NE(decode_problem(bytes_of("P1\n33313#23332\n3")).find("declares 33313x23332 px, more than"),
            std::string::npos);
  std::string pbm_why;
  const auto pbm = bytes_of("P1 4#2\n0101\n0110\n");
  const cv::Mat pbm_img = decode_grey_image(pbm.data(), pbm.size(), &pbm_why);
  ASSERT_FALSE(pbm_img.empty()) << pbm_why;
  EXPECT_EQ(pbm_img.size(), cv::Size(4, 2));  // as OpenCV reads it: 4 wide, 2 high
  // fuzz_image_decode, 10-minute run: a TileWidth without TileLength makes libtiff read tiles of RowsPerStrip
  // rows, so OpenCV's buffer was 18761 x 16392 RGBA px (1.2 GB) for a 32x247 image the header check passed.
  EXPECT_NE(decode_problem(tiff(32, 247, 16392, 18761)).find("strips or tiles hold 307530312 px"),
            std::string::npos);
  // Fuzzing, 26 Nov: the same with the TileWidth typed SSHORT, which the header check skipped and libtiff reads.
  EXPECT_NE(decode_problem(tiff(32, 247, 16392, 18761, 8)).find("strips or tiles hold 307530312 px"),
            std::string::npos);
  EXPECT_NE(decode_problem(tiff(32, 247, 16392, 18761, 3)).find("strips or tiles hold 307530312 px"),
            std::string::npos);
  EXPECT_NE(decode_problem(tiff(32, 247, 200000, 255, 1)).find("strips or tiles hold 51000000 px"),
            std::string::npos);
  // The same TIFF with sane strips decodes.
  std::string why;
  const auto ok = tiff(4, 2, 2);
  const cv::Mat img = decode_grey_image(ok.data(), ok.size(), &why);
  ASSERT_FALSE(img.empty()) << why;
  EXPECT_EQ(img.size(), cv::Size(4, 2));
  EXPECT_EQ(img.at<unsigned char>(1, 3), 210);
}

TEST(FuzzRegressions, ImageHeadersOfEveryAcceptedFormat) {
  cv::Mat grey(6, 8, CV_8UC1);
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 8; ++c) grey.at<unsigned char>(r, c) = static_cast<unsigned char>(10 * r + c);
  cv::Mat colour;
  cv::merge(std::vector<cv::Mat>{grey, grey, grey}, colour);
  for (const char* ext : {".png", ".pgm", ".pbm", ".ppm", ".jpg", ".bmp", ".tiff"}) {
    std::vector<unsigned char> buf;
    ASSERT_TRUE(io::codecs::imencode(ext, std::string(ext) == ".ppm" ? colour : grey, buf)) << ext;
    const auto h = read_image_header(buf.data(), buf.size());
    ASSERT_TRUE(h.has_value()) << ext;
    EXPECT_EQ(h->width, 8) << ext;
    EXPECT_EQ(h->height, 6) << ext;
    EXPECT_EQ(image_header_problem(*h), "") << ext;
    std::string why;
    const cv::Mat img = decode_grey_image(buf.data(), buf.size(), &why);
    ASSERT_EQ(img.size(), cv::Size(8, 6)) << ext << ": " << why;
    EXPECT_EQ(img.type(), CV_8UC1) << ext;
  }
  // Truncated headers are no image.
  std::vector<unsigned char> png;
  io::codecs::imencode(".png", grey, png);
  png.resize(20);
  EXPECT_FALSE(read_image_header(png.data(), png.size()).has_value());
}

}  // namespace
}  // namespace rtslam::io
