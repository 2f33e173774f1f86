// Live input (io/camera_source.hpp): the frame timestamp rule (the driver's time when plausible on the steady clock,
// else the grab time, always increasing), the camera:SPEC parsing, and a short MJPG video standing in for a device:
// played in a loop, paced at its rate, grey, stamped by the steady clock; opening errors are one line naming the
// device. No camera is needed (none is opened).
#include <gtest/gtest.h>

#include <chrono>
#include <variant>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>  // cv::CAP_*

#include "io_test_util.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/io/camera_source.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/io/dataset.hpp"

namespace rtslam::io {
namespace {


TEST(CameraFrameTime, TakesThePlausibleDriverTimeElseTheGrabTime) {
  const TimeNs grab = 5'000 * kNsPerSecond;  // 5000 s of uptime
  // The driver stamped the frame 12.5 ms before the grab returned (exposure end, then transfer): taken.
  EXPECT_EQ(camera_frame_time(1e-6 * static_cast<double>(grab - 12'500'000), grab, 0), grab - 12'500'000);
  // None (OpenCV gives 0 or -1), NaN, another clock (wall clock since 1970), or in the future: the grab time.
  EXPECT_EQ(camera_frame_time(0.0, grab, 0), grab);
  EXPECT_EQ(camera_frame_time(-1.0, grab, 0), grab);
  EXPECT_EQ(camera_frame_time(std::nan(""), grab, 0), grab);
  EXPECT_EQ(camera_frame_time(1.7e12, grab, 0), grab);
  EXPECT_EQ(camera_frame_time(1e-6 * static_cast<double>(grab + 5 * kNsPerMs), grab, 0), grab);
  EXPECT_EQ(camera_frame_time(1e-6 * static_cast<double>(grab - 2 * kNsPerSecond), grab, 0), grab);
  // Not after the previous frame: the grab time; and times always increase.
  EXPECT_EQ(camera_frame_time(1e-6 * static_cast<double>(grab - 10 * kNsPerMs), grab, grab - 10 * kNsPerMs), grab);
  EXPECT_EQ(camera_frame_time(0.0, grab, grab), grab + 1);
}

TEST(CameraSpec, ParsesDeviceNumbersDevicePathsAndVideoFiles) {
  const CameraSpec a = CameraSpec::parse("0");
  EXPECT_TRUE(a.is_device);
  EXPECT_EQ(a.index, 0);
  EXPECT_EQ(a.path, "/dev/video0");
  const CameraSpec b = CameraSpec::parse("/dev/video12");
  EXPECT_TRUE(b.is_device);
  EXPECT_EQ(b.index, 12);
  test::TempDir dir;
  test::write_text(dir / "x.avi", "not a video");
  const CameraSpec c = CameraSpec::parse(dir / "x.avi");
  EXPECT_FALSE(c.is_device);
  EXPECT_EQ(c.path, dir / "x.avi");
  try {
    CameraSpec::parse("front");
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("camera:front: not a camera", 0), 0u) << e.what();
  }
}

/// A short MJPG AVI (OpenCV's own encoder: no codec library needed) of `n` 64x48 colour frames whose brightness is
/// 20 + 10 i, at `fps`.
void write_video(const std::string& path, int n, double fps) {
  const auto w = io::codecs::open_video_writer(path, cv::CAP_OPENCV_MJPEG, io::codecs::fourcc('M', 'J', 'P', 'G'), fps,
                                               cv::Size(64, 48), true);
  ASSERT_TRUE(w) << path;
  for (int i = 0; i < n; ++i) w->write(cv::Mat(48, 64, CV_8UC3, cv::Scalar::all(20 + 10 * i)));
}

TEST(CameraSource, AVideoStandsInForADeviceLoopedAndPacedAtItsRate) {
  test::TempDir dir;
  write_video(dir / "cam.avi", 5, 10.0);
  constexpr double kRateHz = 100.0;
  CameraSource src(CameraSpec::parse(dir / "cam.avi"), cv::Size(64, 48), kRateHz, BadInputPolicy::Error);
  EXPECT_EQ(src.rate_hz(), kRateHz);
  const auto wall0 = std::chrono::steady_clock::now();
  std::vector<TimeNs> t;
  std::vector<double> brightness;
  for (int k = 0; k < 12; ++k) {
    auto m = src.next();
    ASSERT_TRUE(m.has_value());
    const auto* f = std::get_if<ImageFrame>(&*m);
    ASSERT_NE(f, nullptr);
    EXPECT_EQ(f->image.type(), CV_8UC1);
    EXPECT_EQ(f->image.size(), cv::Size(64, 48));
    t.push_back(f->t);
    brightness.push_back(cv::mean(f->image)[0]);
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  // Endless: 12 frames of a 5-frame file, frame 5 is frame 0 again (JPEG: near, not equal, values).
  EXPECT_EQ(src.loops(), 2u);
  EXPECT_NEAR(brightness[5], brightness[0], 2.0);
  EXPECT_NEAR(brightness[4], 60.0, 3.0);
  EXPECT_EQ(src.stats().images, 12u);
  // Paced at 100 Hz by the wall clock (the file says 10 Hz: the option wins; 11 intervals take 0.11 s, 1.1 s at
  // the file's rate), stamped by the steady clock. The last stamp is measured from before the first read, not from
  // the first stamp: on a loaded machine the first frame may be released late (5.5 ms under ctest -j4 on 2 cores),
  // which shortens the span between the stamps but never releases the last frame before its time.
  EXPECT_GE(wall_s, 0.105);
  EXPECT_LT(wall_s, 1.0);
  const TimeNs wall0_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(wall0.time_since_epoch()).count();
  EXPECT_GE(to_seconds(t.back() - wall0_ns), 0.105);
  for (std::size_t k = 1; k < t.size(); ++k) EXPECT_GT(t[k], t[k - 1]);
  const TimeNs now = std::chrono::duration_cast<std::chrono::nanoseconds>(
                         std::chrono::steady_clock::now().time_since_epoch()).count();
  EXPECT_LE(t.back(), now);
  EXPECT_GT(t.back(), now - kNsPerSecond);
}

TEST(CameraSource, AFrameOfAnotherSizeThanTheCalibrationIsAnError) {
  test::TempDir dir;
  write_video(dir / "cam.avi", 3, 50.0);
  CameraSource src(CameraSpec::parse(dir / "cam.avi"), cv::Size(752, 480), 0.0, BadInputPolicy::Error);
  EXPECT_EQ(src.rate_hz(), 50.0);  // the file's
  try {
    src.next();
    FAIL() << "no error";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("frame is 64x48, the calibration says 752x480"), std::string::npos)
        << e.what();
  }
}

TEST(CameraSource, SkippingEveryFrameEndsInAnErrorNotAnEndlessWait) {
  // --bad-input skip and a device that ignores the calibration's size: every frame is skipped. The stream would
  // never yield (and a run could not be interrupted while it waited): after kMaxSkippedInARow frames it fails.
  test::TempDir dir;
  write_video(dir / "cam.avi", 3, 50.0);
  CameraSource src(CameraSpec::parse(dir / "cam.avi"), cv::Size(752, 480), 1000.0, BadInputPolicy::Skip);
  try {
    src.next();
    FAIL() << "no error";
  } catch (const IoError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(fmt::format("{} frames in a row could not be used", CameraSource::kMaxSkippedInARow)),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("the calibration says 752x480"), std::string::npos) << what;
  }
  EXPECT_EQ(src.stats().wrong_size_images, static_cast<std::size_t>(CameraSource::kMaxSkippedInARow));
  EXPECT_EQ(src.stats().images, 0u);
}

TEST(CameraDataset, NeedsACalibrationAndNamesAMissingDevice) {
  test::TempDir dir;
  write_video(dir / "cam.avi", 3, 50.0);
  try {
    open_dataset("camera:" + (dir / "cam.avi"));
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("needs its calibration: give --calibration FILE"), std::string::npos)
        << e.what();
  }
  test::write_text(dir / "cam.json", R"({"model": "pinhole", "width": 64, "height": 48, "focal_length_x": 50,
    "focal_length_y": 50, "principal_point_x": 31.5, "principal_point_y": 23.5})");
  DatasetOptions o;
  o.calibration = dir / "cam.json";
  try {
    open_dataset("camera:97", o);
    FAIL() << "no error";
  } catch (const IoError& e) {
    EXPECT_EQ(std::string(e.what()).rfind("/dev/video97: no such camera device", 0), 0u) << e.what();
  }
  o.duration_s = 0.05;
  Dataset ds = open_dataset("camera:" + (dir / "cam.avi"), o);
  EXPECT_EQ(ds.kind, "camera");
  EXPECT_FALSE(ds.rig.imu.has_value());
  EXPECT_EQ(ds.rig.cameras.front().rate_hz, 50.0);
  int frames = 0;
  while (ds.source->next()) ++frames;  // the --stop-after window ends the endless stream
  EXPECT_GE(frames, 2);
  EXPECT_LE(frames, 4);
}

}  // namespace
}  // namespace rtslam::io
