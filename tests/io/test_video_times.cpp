// Video frame times (io::VideoSource): the container's presentation times, on a Matroska file written here with
// libavformat with chosen times (a variable frame rate, as phones record): OpenCV's writer only writes constant rates.
extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
}

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <thread>
#include <vector>

#include "io_test_util.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/io/camera_source.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/prefetch.hpp"
#include "rtslam/io/realtime.hpp"

namespace rtslam::io {
namespace {

using test::TempDir;
using test::write_text;

constexpr int kWidth = 64, kHeight = 48;

// A Matroska file of MJPEG frames (grey level 40 i) at the given presentation times (ms); false if this FFmpeg
// cannot write one.
bool write_mkv(const std::string& path, const std::vector<std::int64_t>& pts_ms) {
  AVFormatContext* oc = nullptr;
  if (avformat_alloc_output_context2(&oc, nullptr, "matroska", path.c_str()) < 0 || oc == nullptr) return false;
  bool ok = false;
  AVStream* st = avformat_new_stream(oc, nullptr);
  if (st != nullptr) {
    st->codecpar->codec_type = AVMEDIA_TYPE_VIDEO;
    st->codecpar->codec_id = AV_CODEC_ID_MJPEG;
    st->codecpar->width = kWidth;
    st->codecpar->height = kHeight;
    st->codecpar->format = AV_PIX_FMT_YUVJ420P;
    st->time_base = AVRational{1, 1000};
    ok = avio_open(&oc->pb, path.c_str(), AVIO_FLAG_WRITE) >= 0 && avformat_write_header(oc, nullptr) >= 0;
    for (std::size_t i = 0; ok && i < pts_ms.size(); ++i) {
      const int level = static_cast<int>(40 * i % 256);
      std::vector<uchar> jpeg;
      cv::imencode(".jpg", cv::Mat(kHeight, kWidth, CV_8UC3, cv::Scalar(level, level, level)), jpeg);
      AVPacket* pkt = av_packet_alloc();
      ok = pkt != nullptr && av_new_packet(pkt, static_cast<int>(jpeg.size())) >= 0;
      if (ok) {
        std::memcpy(pkt->data, jpeg.data(), jpeg.size());
        pkt->stream_index = st->index;
        pkt->pts = pkt->dts = av_rescale_q(pts_ms[i], AVRational{1, 1000}, st->time_base);
        pkt->duration = i + 1 < pts_ms.size() ? pts_ms[i + 1] - pts_ms[i] : 33;
        pkt->flags |= AV_PKT_FLAG_KEY;
        ok = av_interleaved_write_frame(oc, pkt) >= 0;
      }
      av_packet_free(&pkt);
    }
    if (ok) ok = av_write_trailer(oc) >= 0;
    if (oc->pb != nullptr) avio_closep(&oc->pb);
  }
  avformat_free_context(oc);
  return ok;
}

std::vector<ImageFrame> drain_images(Source& src) {
  std::vector<ImageFrame> out;
  while (auto m = src.next()) {
    if (auto* img = std::get_if<ImageFrame>(&*m)) out.push_back(std::move(*img));
  }
  return out;
}

// The next measurement of `src`, an image (an empty one, the test failed, otherwise).
ImageFrame next_image(Source& src) {
  std::optional<Measurement> m = src.next();
  EXPECT_TRUE(m.has_value());
  if (!m) return {};
  auto* f = std::get_if<ImageFrame>(&*m);
  EXPECT_NE(f, nullptr);
  return f != nullptr ? std::move(*f) : ImageFrame{};
}

class VideoTimes : public ::testing::Test {
 protected:
  void write(const std::vector<std::int64_t>& pts_ms) {
    ASSERT_TRUE(write_mkv(video, pts_ms)) << "libavformat could not write " << video;
    write_calibration();
  }
  void write_calibration() {
    write_text(dir / "calibration.yaml", "cameras:\n  - name: cam0\n    width: 64\n    height: 48\n"
                                         "    intrinsics: [50, 50, 32, 24]\n");
  }
  TempDir dir;
  std::string video = dir / "phone.mkv";
};

TEST_F(VideoTimes, AVariableFrameRateKeepsEachFramesPresentationTime) {
  // Review of 30 Nov: frames were timed i / rate with the rate OpenCV reports; for this file that is the time
  // base's 1000 "fps" (frames 1 ms apart), and its "frame count" of 333 made the end look like a truncation.
  const std::vector<std::int64_t> pts = {0, 50, 150, 175, 300, 333, 400};
  write(pts);
  if (HasFatalFailure()) return;
  Dataset ds = open_dataset(video);
  EXPECT_EQ(ds.kind, "video");
  // The nominal rate: one over the median interval of the first frames (50, 100, 25, 125 ms: 50 ms).
  EXPECT_NEAR(ds.rig.cameras[0].rate_hz, 20.0, 1e-9);
  const std::vector<ImageFrame> frames = drain_images(*ds.source);
  ASSERT_EQ(frames.size(), pts.size());
  for (std::size_t i = 0; i < pts.size(); ++i) {
    EXPECT_EQ(frames[i].t, pts[i] * 1'000'000) << "frame " << i;
    EXPECT_NEAR(frames[i].image.at<std::uint8_t>(10, 10), 40 * i, 6) << "frame " << i;  // MJPEG is lossy
  }
  EXPECT_EQ(ds.source->stats().problems(), 0u);
}

TEST_F(VideoTimes, TheRateOptionTimesFramesAtIOverTheRate) {
  write({0, 50, 150, 175, 300});
  if (HasFatalFailure()) return;
  DatasetOptions o;
  o.rate_hz = 10.0;
  Dataset ds = open_dataset(video, o);
  EXPECT_DOUBLE_EQ(ds.rig.cameras[0].rate_hz, 10.0);
  const std::vector<ImageFrame> frames = drain_images(*ds.source);
  ASSERT_EQ(frames.size(), 5u);
  for (std::size_t i = 0; i < frames.size(); ++i) EXPECT_EQ(frames[i].t, static_cast<TimeNs>(i) * 100'000'000);
}

TEST_F(VideoTimes, ARepeatedPresentationTimeIsBadInput) {
  // Matroska allows equal times; a second frame at the same time cannot be placed in the stream.
  write({0, 50, 100, 100, 150, 200});
  if (HasFatalFailure()) return;
  {
    Dataset ds = open_dataset(video);
    EXPECT_THROW_WITH(drain_images(*ds.source), DataError, "phone.mkv#3: duplicate presentation time 100.000 ms");
  }
  DatasetOptions skip;
  skip.bad_input = BadInputPolicy::Skip;
  Dataset ds = open_dataset(video, skip);
  const std::vector<ImageFrame> frames = drain_images(*ds.source);
  ASSERT_EQ(frames.size(), 5u);
  EXPECT_EQ(frames[3].t, 150'000'000);
  EXPECT_EQ(ds.source->stats().duplicate_timestamps, 1u);
}

TEST_F(VideoTimes, AFileCutShortIsStillATruncationAtAVariableRate) {
  std::vector<std::int64_t> pts;
  for (int i = 0; i < 60; ++i) pts.push_back(i * 40 + (i % 3 == 0 ? 7 : 0));  // 25 Hz with jitter: 2.4 s
  write(pts);
  if (HasFatalFailure()) return;
  const std::uintmax_t size = std::filesystem::file_size(video);
  std::filesystem::resize_file(video, size / 2);
  Dataset ds = open_dataset(video);
  EXPECT_THROW_WITH(drain_images(*ds.source), IoError, "phone.mkv: the video ends at frame");
}

// Review of 30 Nov: OpenCV 4.6 gives no presentation time (0) for the frames the H.264 decoder still holds when the
// file ends (with B-frames); those came out as times going backwards, and with --rate as a truncation.
TEST_F(VideoTimes, TheLastFramesOfAnH264FileKeepIncreasingTimes) {
  video = dir / "clip.mp4";
  {
    cv::VideoWriter w(video, cv::VideoWriter::fourcc('a', 'v', 'c', '1'), 30.0, cv::Size(kWidth, kHeight), true);
    if (!w.isOpened()) GTEST_SKIP() << "OpenCV has no H.264 encoder here";
    cv::Mat img(kHeight, kWidth, CV_8UC3);
    cv::RNG rng(5);
    for (int i = 0; i < 120; ++i) {
      rng.fill(img, cv::RNG::UNIFORM, 0, 255);
      w.write(img);
    }
  }
  write_calibration();
  for (const double rate : {0.0, 30.0}) {
    DatasetOptions o;
    o.rate_hz = rate;
    Dataset ds = open_dataset(video, o);
    EXPECT_DOUBLE_EQ(ds.rig.cameras[0].rate_hz, 30.0);
    const std::vector<ImageFrame> frames = drain_images(*ds.source);
    ASSERT_EQ(frames.size(), 120u) << "rate " << rate;
    for (std::size_t i = 0; i < frames.size(); ++i) {
      EXPECT_NEAR(static_cast<double>(frames[i].t), static_cast<double>(i) * 1e9 / 30.0, 0.5e6) << "frame " << i;
    }
    EXPECT_EQ(ds.source->stats().problems(), 0u);
  }
}

// A given rate re-times the frames; the end is still judged in the file's own frames. A 10 fps file read at 100 Hz
// ended "truncated" (its last frame 0.1 s before the container's duration, against a slack of 5 frames at 100 Hz),
// and so did every pass of camera:FILE --rate 100 over it.
TEST_F(VideoTimes, AGivenRateDoesNotMakeTheFilesEndATruncation) {
  video = dir / "slow.avi";
  constexpr int kFrames = 30;  // 3 s: below 5 s, the slack of 5 frames is larger than that of 2 % of the duration
  {
    cv::VideoWriter w(video, cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10.0,
                      cv::Size(kWidth, kHeight), true);
    ASSERT_TRUE(w.isOpened());
    cv::Mat img(kHeight, kWidth, CV_8UC3);
    cv::RNG rng(3);
    for (int i = 0; i < kFrames; ++i) {
      rng.fill(img, cv::RNG::UNIFORM, 0, 255);  // (noise: frames of a size that puts most of the file after the header)
      w.write(img);
    }
  }
  write_calibration();
  DatasetOptions o;
  o.rate_hz = 100.0;
  {
    Dataset ds = open_dataset(video, o);
    const std::vector<ImageFrame> frames = drain_images(*ds.source);
    ASSERT_EQ(frames.size(), static_cast<std::size_t>(kFrames));
    EXPECT_EQ(frames.back().t, (kFrames - 1) * 10'000'000);
    EXPECT_EQ(ds.source->stats().problems(), 0u);
  }
  // Cut short, the same file is still a truncation at the given rate.
  std::filesystem::resize_file(video, std::filesystem::file_size(video) * 6 / 10);
  Dataset cut = open_dataset(video, o);
  EXPECT_THROW_WITH(drain_images(*cut.source), IoError, "slow.avi: the video ends at frame");
}

// camera:FILE (a video standing in for a live camera) releases each frame when its time in the file comes, by the
// wall clock, and loops one nominal interval after the last frame. Before, it paced frames at OpenCV's rate, for
// this file the Matroska time base's 1000 "fps": all ten frames within ~10 ms.
TEST_F(VideoTimes, AVideoStandingInForACameraKeepsItsVariableIntervals) {
  const std::vector<std::int64_t> pts = {0, 40, 60, 140, 160};
  write(pts);
  if (HasFatalFailure()) return;
  CameraSource src(CameraSpec::parse(video), cv::Size(kWidth, kHeight), 0.0, BadInputPolicy::Error);
  // The nominal rate: one over the lower median of 40, 20, 80, 20 ms.
  EXPECT_NEAR(src.rate_hz(), 50.0, 1e-9);
  const TimeNs start = std::chrono::duration_cast<std::chrono::nanoseconds>(
                           std::chrono::steady_clock::now().time_since_epoch()).count();
  std::vector<TimeNs> t;
  std::vector<double> level;
  for (int k = 0; k < 10; ++k) {
    const ImageFrame f = next_image(src);
    ASSERT_FALSE(f.image.empty()) << "frame " << k;
    t.push_back(f.t);
    level.push_back(f.image.at<std::uint8_t>(10, 10));
  }
  EXPECT_EQ(src.loops(), 1u);
  // Due times from the first frame: the file's times, then the second pass 160 + 20 ms after the first.
  const std::vector<double> due_ms = {0, 40, 60, 140, 160, 180, 220, 240, 320, 340};
  for (std::size_t k = 0; k < t.size(); ++k) {
    // Never released early (the pacing starts at the first next(), after `start`); late by the machine's scheduling
    // at most, loosely bounded.
    EXPECT_GE(1e-6 * static_cast<double>(t[k] - start), due_ms[k]) << "frame " << k;
    const double dt_ms = 1e-6 * static_cast<double>(t[k] - t[0]);
    EXPECT_LE(dt_ms, due_ms[k] + 250.0) << "frame " << k;
    EXPECT_NEAR(level[k], 40.0 * static_cast<double>(k % 5), 6.0) << "frame " << k;  // MJPEG is lossy
  }
  EXPECT_EQ(src.stats().images, 10u);
  EXPECT_EQ(src.stats().problems(), 0u);
}

// Review of 30 Nov: a stopped live run waited out the gap before the stand-in's next frame (the acquisition thread
// slept in it while stop() joined that thread): 4 s for a 4 s gap, forever for a corrupt far-future time.
TEST_F(VideoTimes, StoppingALiveRunEndsTheStandInsWaitForItsNextFrame) {
  write({0, 60000});  // a minute between the first frame and the second
  if (HasFatalFailure()) return;
  auto camera = std::make_unique<CameraSource>(CameraSpec::parse(video), cv::Size(kWidth, kHeight), 0.0,
                                               BadInputPolicy::Error);
  std::unique_ptr<Source> chain = std::move(camera);
  ASSERT_EQ(start_prefetch(chain, 1), 1);  // as rtslam run reads a camera: prefetched, then released live
  RealtimeSource live(std::move(chain), 1.0, RealtimeSource::kDefaultMaxQueue, true);
  next_image(live);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));  // the acquisition now waits for the second frame
  const auto t0 = std::chrono::steady_clock::now();
  live.stop();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0);
  EXPECT_FALSE(live.next().has_value());
  EXPECT_EQ(live.stats().images, 1u);
}

// A stand-in's passes: bad frames are counted on every pass and the counts survive a pass that cannot be opened; the
// end of a truncated file only starts the next pass.
TEST_F(VideoTimes, AStandInCountsBadFramesOverItsPassesAndLoopsATruncatedFile) {
  write({0, 20, 40, 40, 60});  // frame 3 repeats frame 2's time
  if (HasFatalFailure()) return;
  {
    CameraSource src(CameraSpec::parse(video), cv::Size(kWidth, kHeight), 0.0, BadInputPolicy::Skip);
    for (int k = 0; k < 8; ++k) next_image(src);  // two passes of 4 frames
    EXPECT_EQ(src.loops(), 1u);
    EXPECT_EQ(src.stats().duplicate_timestamps, 2u);
    EXPECT_EQ(src.stats().images, 8u);
    std::filesystem::remove(video);  // the third pass cannot be opened: one line naming the file
    EXPECT_THROW_WITH(src.next(), IoError, "phone.mkv: file not found");
    EXPECT_EQ(src.stats().duplicate_timestamps, 2u);  // the passes' counts kept
    EXPECT_EQ(src.stats().images, 8u);
  }
  std::vector<std::int64_t> pts;
  for (int i = 0; i < 60; ++i) pts.push_back(i * 40);
  write(pts);
  if (HasFatalFailure()) return;
  std::filesystem::resize_file(video, std::filesystem::file_size(video) / 2);
  CameraSource src(CameraSpec::parse(video), cv::Size(kWidth, kHeight), 1000.0, BadInputPolicy::Error);
  std::size_t frames = 0;
  while (src.loops() < 2) {
    next_image(src);
    ++frames;
    ASSERT_LT(frames, 200u);
  }
  EXPECT_GT(frames, 20u);
  EXPECT_EQ(src.stats().problems(), 0u);
}

}  // namespace
}  // namespace rtslam::io
