// The live input's parts: io::LiveSource (producer threads merged into one time-ordered stream; the ROS node and
// the live camera–IMU rig feed it), io::ImuStreamReader (an IMU's text lines from a FIFO, as they arrive) and
// io::LiveRigSource (a camera thread and an IMU-stream thread feeding a LiveSource).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/io/imu_stream.hpp"
#include "rtslam/io/live_rig.hpp"
#include "rtslam/io/live_source.hpp"
#include "rtslam/io/realtime.hpp"

namespace rtslam::io {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

TimeNs now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
}

ImageFrame image_at(TimeNs t) {
  ImageFrame f;
  f.t = t;
  f.image = cv::Mat(2, 2, CV_8UC1, cv::Scalar(static_cast<double>(t % 200)));
  f.path = "test#" + std::to_string(t);
  return f;
}

ImuSample imu_at(TimeNs t) {
  ImuSample s;
  s.t = t;
  s.accel = Eigen::Vector3d(0.0, 0.0, 9.81);
  return s;
}

/// (t, is image) of a measurement.
std::pair<TimeNs, bool> tag(const std::optional<Measurement>& m) {
  EXPECT_TRUE(m.has_value());
  if (!m) return {-1, false};
  return {time_of(*m), std::holds_alternative<ImageFrame>(*m)};
}

TEST(LiveSource, AnImageWaitsForTheImuSampleThatCoversIt) {
  LiveSource::Options o;
  o.with_imu = true;
  o.max_image_wait_s = 30.0;
  LiveSource src(o);
  src.push_image(image_at(10));
  src.push_imu(imu_at(5));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{5}, false));
  std::thread late_imu([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    src.push_imu(imu_at(10));
    src.push_imu(imu_at(15));
  });
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{10}, false));  // IMU first at equal times
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{10}, true));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{15}, false));
  late_imu.join();
  src.close();
  EXPECT_FALSE(src.next().has_value());
  EXPECT_EQ(src.stats().images, 1u);
  EXPECT_EQ(src.stats().imu_samples, 3u);
}

TEST(LiveSource, WithoutImuImagesGoThroughAtOnce) {
  LiveSource src(LiveSource::Options{});
  src.push_image(image_at(10));
  src.push_image(image_at(20));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{10}, true));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{20}, true));
}

TEST(LiveSource, AnImageWaitsForTheImuAtMostTheMaximumWait) {
  LiveSource::Options o;
  o.with_imu = true;
  o.max_image_wait_s = 0.05;
  LiveSource src(o);
  src.push_imu(imu_at(5));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{5}, false));
  const auto start = std::chrono::steady_clock::now();
  src.push_image(image_at(10));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{10}, true));
  EXPECT_GE(std::chrono::steady_clock::now() - start, std::chrono::milliseconds(45));
}

// Before the IMU's first sample an image that has waited is dropped, not released: an inertial filter cannot use it,
// and an IMU stream started late would otherwise fill the pipeline with frames it can only park.
TEST(LiveSource, ImagesThatWaitedWhileNoImuSampleHadComeAreDroppedAndCounted) {
  LiveSource::Options o;
  o.with_imu = true;
  o.max_image_wait_s = 0.02;
  LiveSource src(o);
  src.push_image(image_at(10));
  src.push_image(image_at(20));
  std::thread imu([&] {
    // Once both frames have waited and been dropped (at most 10 s).
    for (int k = 0; k < 2000 && src.stats().live_images_before_imu < 2; ++k) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    src.push_imu(imu_at(25));
    src.push_image(image_at(30));
    src.push_imu(imu_at(35));
  });
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{25}, false));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{30}, true));
  imu.join();
  EXPECT_EQ(src.stats().live_images_before_imu, 2u);
  EXPECT_EQ(src.stats().live_dropped_images, 0u);
  EXPECT_EQ(src.stats().problems(), 0u);  // not bad input
}

// Whatever the timing, a frame that no IMU sample covers is never released while none has come: the decision
// to drop it and the one to release it read the clock once (read twice, a deadline passing between the two reads
// released the frame to the filter, which then ended with "the IMU stream ends before the images" instead of "no
// IMU sample came"). Frames pushed every few microseconds, each waiting at most 40 us, wake the consumer near its
// front frame's deadline many thousand times.
TEST(LiveSource, NoFrameIsReleasedBeforeTheImusFirstSampleWhateverTheTiming) {
  LiveSource::Options o;
  o.with_imu = true;
  o.max_image_wait_s = 40e-6;
  o.image_capacity = 1000;
  LiveSource src(o);
  std::atomic<std::size_t> released{0};
  std::thread consumer([&] {
    while (auto m = src.next()) {
      if (std::holds_alternative<ImageFrame>(*m)) ++released;
    }
  });
  const auto end = Clock::now() + std::chrono::milliseconds(400);
  TimeNs t = 0;
  std::size_t pushed = 0;
  while (Clock::now() < end) {
    src.push_image(image_at(t += 1000));
    ++pushed;
    const auto next = Clock::now() + std::chrono::microseconds(7);
    while (Clock::now() < next) std::this_thread::yield();
  }
  src.close();
  consumer.join();
  EXPECT_EQ(released.load(), 0u) << "of " << pushed << " frames";
  EXPECT_EQ(src.stats().live_images_before_imu + src.stats().live_dropped_images, pushed);
  RecordProperty("frames", static_cast<int>(pushed));
}

// A run limited in time (--stop-after) processes nothing before the IMU's first sample, so its window of processed
// times would never close on a silent IMU: the source ends itself once the dropped frames span that time.
TEST(LiveSource, WithoutAnyImuSampleTheStreamEndsOnceTheDroppedFramesSpanTheTimeToProcess) {
  LiveSource::Options o;
  o.with_imu = true;
  o.max_image_wait_s = 0.001;
  o.end_without_imu_after_s = 0.05;
  constexpr TimeNs kMs = 1'000'000;
  const auto frame = [&](TimeNs k) { return image_at(1000 * kMs + k * 10 * kMs); };  // every 10 ms
  {  // Frames spanning less than 50 ms are dropped and the stream goes on; the one at 50 ms ends it.
    LiveSource src(o);
    for (TimeNs k = 0; k < 4; ++k) src.push_image(frame(k));
    std::atomic<bool> ended{false};
    std::optional<Measurement> last;
    std::thread consumer([&] {
      last = src.next();
      ended = true;
    });
    for (int k = 0; k < 2000 && src.stats().live_images_before_imu < 4; ++k) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    EXPECT_EQ(src.stats().live_images_before_imu, 4u);
    EXPECT_FALSE(ended.load()) << "ended before the dropped frames spanned 50 ms";
    src.push_image(frame(5));
    consumer.join();
    EXPECT_FALSE(last.has_value());
    EXPECT_EQ(src.stats().live_images_before_imu, 5u);
    src.push_image(frame(6));  // ignored: the stream has ended
    EXPECT_FALSE(src.next().has_value());
    EXPECT_EQ(src.stats().live_images_before_imu, 5u);
  }
  {  // The frames queued behind the one that ends the stream are dropped and counted too.
    LiveSource src(o);
    for (TimeNs k = 0; k < 8; ++k) src.push_image(frame(k));
    EXPECT_FALSE(src.next().has_value());
    EXPECT_EQ(src.stats().live_images_before_imu, 8u);
  }
  o.end_without_imu_after_s = -1.0;
  EXPECT_THROW(LiveSource{o}, ConfigError);
}

TEST(LiveSource, BadStampsAndValuesAreSkippedAndCounted) {
  LiveSource::Options o;
  o.with_imu = true;
  LiveSource src(o);
  src.push_imu(imu_at(5));
  src.push_imu(imu_at(5));  // duplicate
  src.push_imu(imu_at(3));  // backwards
  ImuSample nan = imu_at(7);
  nan.gyro.x() = std::numeric_limits<double>::quiet_NaN();
  src.push_imu(nan);
  src.push_imu(imu_at(20));
  src.push_image(image_at(10));
  src.push_image(image_at(10));  // duplicate
  src.push_image(image_at(8));   // backwards
  src.report_bad_image("/cam0/image_raw message seq 3: encoding 'mono16' is not supported");
  src.close();
  std::vector<std::pair<TimeNs, bool>> got;
  while (auto m = src.next()) got.emplace_back(time_of(*m), std::holds_alternative<ImageFrame>(*m));
  EXPECT_EQ(got, (std::vector<std::pair<TimeNs, bool>>{{5, false}, {10, true}, {20, false}}));
  const SourceStats& s = src.stats();
  EXPECT_EQ(s.duplicate_timestamps, 2u);
  EXPECT_EQ(s.backwards_timestamps, 2u);
  EXPECT_EQ(s.non_finite, 1u);
  EXPECT_EQ(s.undecodable_images, 1u);
  EXPECT_EQ(s.messages.size(), 6u);
}

TEST(LiveSource, AFullQueueDropsItsOldestElement) {
  LiveSource::Options o;
  o.image_capacity = 2;
  o.imu_capacity = 1;
  LiveSource src(o);
  for (TimeNs t : {10, 20, 30}) src.push_image(image_at(t));
  src.push_imu(imu_at(1));
  src.push_imu(imu_at(2));
  EXPECT_EQ(src.dropped_images(), 1u);
  EXPECT_EQ(src.dropped_imu_samples(), 1u);
  src.close();
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{2}, false));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{20}, true));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{30}, true));
  EXPECT_FALSE(src.next().has_value());
  src.push_image(image_at(40));  // after close: ignored
  EXPECT_FALSE(src.next().has_value());
}

TEST(LiveSource, ProducerThreadsAndTheConsumerSeeOneTimeOrderedStream) {
  LiveSource::Options o;
  o.with_imu = true;
  o.image_capacity = 1000;
  o.imu_capacity = 10000;
  o.max_image_wait_s = 30.0;
  LiveSource src(o);
  constexpr int kImages = 50;
  constexpr int kImuPerImage = 10;
  // The camera's messages arrive before the IMU samples that cover them (as when the IMU driver lags): the source
  // holds each image until its IMU has come, so the consumer sees one time-ordered stream.
  src.push_imu(imu_at(90));  // the IMU has started
  std::thread producers([&] {
    std::thread image_thread([&] {
      for (int k = 0; k < kImages; ++k) src.push_image(image_at(100 + 100 * k + 5));
    });
    image_thread.join();
    std::thread imu_thread([&] {
      for (int k = 0; k <= kImages * kImuPerImage; ++k) src.push_imu(imu_at(100 + 10 * k));
    });
    imu_thread.join();
    src.close();
  });
  std::size_t images = 0, imu = 0;
  TimeNs last = std::numeric_limits<TimeNs>::min();
  bool ordered = true;
  while (auto m = src.next()) {
    ordered = ordered && time_of(*m) >= last;
    last = time_of(*m);
    (std::holds_alternative<ImageFrame>(*m) ? images : imu) += 1;
  }
  producers.join();
  EXPECT_TRUE(ordered);
  EXPECT_EQ(images, static_cast<std::size_t>(kImages));
  EXPECT_EQ(imu, static_cast<std::size_t>(kImages * kImuPerImage + 2));
}

TEST(LiveSource, RefusesEmptyQueuesAndUnboundedWaits) {
  LiveSource::Options o;
  o.image_capacity = 0;
  EXPECT_THROW(LiveSource{o}, ConfigError);
  o.image_capacity = 1;
  o.max_image_wait_s = std::numeric_limits<double>::infinity();
  EXPECT_THROW(LiveSource{o}, ConfigError);
  o.max_image_wait_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(LiveSource{o}, ConfigError);
}

TEST(LiveSource, UnderTheErrorPolicyTheFirstProblemEndsTheStreamAfterWhatCameBefore) {
  LiveSource::Options o;
  o.policy = BadInputPolicy::Error;
  LiveSource src(o);
  src.push_imu(imu_at(5));
  src.push_image(image_at(6));
  src.push_imu(imu_at(5));   // a repeated stamp: the stream ends here
  src.push_imu(imu_at(10));  // ignored
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{5}, false));
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{6}, true));
  try {
    src.next();
    FAIL() << "no error";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("stamp repeats"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(src.next().has_value());
}

TEST(LiveSource, AProducerFailureIsThrownAfterTheQueuedMeasurements) {
  LiveSource src(LiveSource::Options{});
  src.push_image(image_at(10));
  src.fail(std::make_exception_ptr(IoError("/dev/video0: the camera stopped delivering frames")));
  src.push_image(image_at(20));  // after the failure: ignored
  EXPECT_EQ(tag(src.next()), std::make_pair(TimeNs{10}, true));
  EXPECT_THROW(src.next(), IoError);
}

// A run stopped (Ctrl-C) while the live source waits for an IMU that never comes: the real-time reader stops, and its
// statistics are the stream's as far as it was read (the frames dropped waiting), not those copied at its start.
TEST(LiveSource, AnInterruptedRealtimeReaderReportsTheFramesDroppedWaitingForTheImu) {
  LiveSource::Options o;
  o.with_imu = true;
  o.max_image_wait_s = 0.01;
  auto owned = std::make_unique<LiveSource>(o);
  LiveSource& live = *owned;
  RealtimeSource rt(std::move(owned), 1.0, RealtimeSource::kDefaultMaxQueue, true);
  std::atomic<bool> stop{false};
  rt.set_interrupt(&stop);
  live.push_image(image_at(10));
  live.push_image(image_at(20));
  std::thread ctrl_c([&] {
    for (int k = 0; k < 2000 && live.stats().live_images_before_imu < 2; ++k) {
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    stop = true;
  });
  EXPECT_FALSE(rt.next().has_value());
  ctrl_c.join();
  EXPECT_EQ(rt.stats().live_images_before_imu, 2u);
}

// ------------------------------------------------------------------------------------------------- ImuStreamReader

/// A FIFO in a fresh folder (removed with it).
struct Fifo {
  fs::path dir, path;
  explicit Fifo(const std::string& name) {
    dir = fs::temp_directory_path() / ("rtslam_test_live_" + name);
    fs::remove_all(dir);
    fs::create_directories(dir);
    path = dir / "imu.fifo";
    EXPECT_EQ(::mkfifo(path.c_str(), 0600), 0);
  }
  ~Fifo() { fs::remove_all(dir); }
};

/// Writes `text` to the FIFO (opened for writing: a reader must have it open), in pieces of `chunk` bytes `pause`
/// apart, then closes it.
void write_fifo(const fs::path& path, const std::string& text, std::size_t chunk = 1 << 20,
                std::chrono::milliseconds pause = std::chrono::milliseconds(0)) {
  const int fd = ::open(path.c_str(), O_WRONLY);
  ASSERT_GE(fd, 0);
  for (std::size_t i = 0; i < text.size(); i += chunk) {
    const std::string piece = text.substr(i, chunk);
    ASSERT_EQ(::write(fd, piece.data(), piece.size()), static_cast<ssize_t>(piece.size()));
    if (pause.count() > 0) std::this_thread::sleep_for(pause);
  }
  ::close(fd);
}

std::vector<ImuSample> drain_imu(LiveSource& live) {
  std::vector<ImuSample> out;
  while (auto m = live.next()) {
    if (auto* s = std::get_if<ImuSample>(&*m)) out.push_back(*s);
  }
  return out;
}

TEST(ImuStreamReader, ReadsHostStampedLinesFromAFifoUntilItsWriterClosesIt) {
  Fifo fifo("host");
  ImuStreamReader reader(fifo.path.string(), ImuStreamReader::Options{});
  LiveSource live(LiveSource::Options{});
  const TimeNs t0 = now_ns();
  const std::string text = fmt::format(
      "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],"
      "a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n"
      "{},0.1,0.2,0.3,9.1,0.1,-3.7\r\n"
      "\n"
      "{} 0.1 0.2 0.3 9.2 0.1 -3.6\n"
      "{},0.1,0.2,x,9.2,0.1,-3.6\n"
      "{},0.1,0.2,0.3,9.3,0.1,-3.5",  // the last line without its newline
      t0, t0 + 5'000'000, t0 + 10'000'000, t0 + 15'000'000);
  std::thread writer([&] { write_fifo(fifo.path, text, 7, std::chrono::milliseconds(1)); });
  EXPECT_TRUE(reader.run(live));  // the writer closed the FIFO
  writer.join();
  live.close();
  const std::vector<ImuSample> s = drain_imu(live);
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s[0].t, t0);
  EXPECT_EQ(s[1].t, t0 + 5'000'000);
  EXPECT_EQ(s[2].t, t0 + 15'000'000);
  EXPECT_EQ(s[0].gyro, Eigen::Vector3d(0.1, 0.2, 0.3));
  EXPECT_EQ(s[2].accel, Eigen::Vector3d(9.3, 0.1, -3.5));
  EXPECT_EQ(live.stats().malformed_lines, 1u);
  ASSERT_EQ(live.stats().messages.size(), 1u);
  EXPECT_NE(live.stats().messages[0].find(fifo.path.string() + ":5: expected 7 numbers"), std::string::npos)
      << live.stats().messages[0];
  EXPECT_EQ(reader.lines(), 6);
}

// A driver stamping on another clock (here 1 ms after some epoch, not CLOCK_MONOTONIC): its first line is bad input
// whose message says which clock to stamp on.
TEST(ImuStreamReader, SamplesStampedOnAnotherClockAreBadInputSayingWhichClock) {
  Fifo fifo("clock");
  ImuStreamReader reader(fifo.path.string(), ImuStreamReader::Options{});
  LiveSource::Options o;
  o.policy = BadInputPolicy::Error;
  LiveSource live(o);
  std::thread writer([&] { write_fifo(fifo.path, "1000000,0,0,0,0,0,9.81\n"); });
  EXPECT_TRUE(reader.run(live));
  writer.join();
  try {
    live.next();
    ADD_FAILURE() << "no error";
  } catch (const DataError& e) {
    const std::string m = e.what();
    EXPECT_EQ(m.rfind(fifo.path.string() + ":1: sample time 0.001000000 s is", 0), 0u) << m;
    EXPECT_NE(m.find("from this machine's CLOCK_MONOTONIC"), std::string::npos) << m;
    EXPECT_NE(m.find("--imu-clock device"), std::string::npos) << m;
  }
}

/// Lines `t,0,0,0,0,0,9.81` for the given device times.
std::string device_lines(const std::vector<TimeNs>& times) {
  std::string text;
  for (TimeNs t : times) text += fmt::format("{},0,0,0,0,0,9.81\n", t);
  return text;
}

/// A device-clock reader (on an empty file: the tests feed it bytes with chosen read times, ImuStreamReader::feed,
/// what run() does with each read) and the live source it feeds.
struct DeviceFeed {
  fs::path file;
  std::optional<ImuStreamReader> reader;
  LiveSource live;
  explicit DeviceFeed(const std::string& name, const LiveSource::Options& live_options = {})
      : file(fs::temp_directory_path() / ("rtslam_test_live_" + name)), live(live_options) {
    std::ofstream(file.string()) << "";
    ImuStreamReader::Options o;
    o.clock = ImuStreamClock::Device;
    reader.emplace(file.string(), o);
  }
  ~DeviceFeed() { fs::remove(file); }
  void feed(const std::string& text, TimeNs read_ns) { reader->feed(text.data(), text.size(), read_ns, live); }
  std::vector<ImuSample> samples() {
    live.close();
    return drain_imu(live);
  }
};

TEST(ImuStreamReader, DeviceTimesKeepTheirIntervalsInBurstsAndBadTimesLeaveTheStreamAlone) {
  DeviceFeed d("device.csv");
  LiveSource& live = d.live;
  const fs::path& file = d.file;
  constexpr TimeNs T = 7'000'000'000, R = 1'000'000'000'000, ms = 1'000'000;
  const auto times = [&](int from, int to) {
    std::vector<TimeNs> t;
    for (int k = from; k < to; ++k) t.push_back(T + 5 * ms * k);
    return t;
  };
  // Samples 5 ms apart sent in bursts of 4 every 20 ms; the first burst read 0 ms after its last sample was
  // sent, the second 0.5 ms after (a slower delivery: the delay estimate keeps the first), the third 1 ms before
  // the first's delay (a faster one: the estimate shrinks by 1 ms).
  const auto feed = [&](const std::string& text, TimeNs read) { d.feed(text, read); };
  feed(device_lines(times(0, 4)), R);
  feed(device_lines(times(4, 8)), R + 20 * ms + ms / 2);
  feed(device_lines(times(8, 12)), R + 39 * ms);
  // A counter that restarted, then a corrupt time far ahead: both bad input, the stream goes on after them.
  feed(device_lines({100, T + 60 * ms + 1'000'000'000'000'000'000LL, T + 60 * ms}), R + 60 * ms);
  const std::vector<ImuSample> s = d.samples();
  ASSERT_EQ(s.size(), 13u);
  for (std::size_t k = 0; k < 8; ++k) EXPECT_EQ(s[k].t, R + (5 * static_cast<TimeNs>(k) - 15) * ms) << k;
  for (std::size_t k = 8; k < 12; ++k) EXPECT_EQ(s[k].t, R + (5 * static_cast<TimeNs>(k) - 16) * ms) << k;
  EXPECT_EQ(s[12].t, R + 44 * ms);
  EXPECT_EQ(live.stats().backwards_timestamps, 1u);
  EXPECT_EQ(live.stats().timestamp_jumps, 1u);
  ASSERT_EQ(live.stats().messages.size(), 2u);
  EXPECT_NE(live.stats().messages[0].find(file.string() + ":13: device time 100 ns goes backwards"),
            std::string::npos)
      << live.stats().messages[0];
  EXPECT_NE(live.stats().messages[1].find(":14: device time"), std::string::npos) << live.stats().messages[1];
}

// The stream's first time was the corrupt one: the lines after it are "backwards" until kReanchorLines of them agree
// with one another; they are then the reference, and the stream goes on.
TEST(ImuStreamReader, ACorruptFirstTimeGivesWayToTheLinesThatAgree) {
  DeviceFeed d("reanchor.csv");
  constexpr TimeNs T = 7'000'000'000, R = 1'000'000'000'000, ms = 1'000'000;
  const std::vector<TimeNs> times = {9'000'000'000'000'000'000LL, T, T + 5 * ms, T + 10 * ms, T + 15 * ms};
  for (std::size_t k = 0; k < times.size(); ++k) d.feed(device_lines({times[k]}), R + static_cast<TimeNs>(k) * 5 * ms);
  const std::vector<ImuSample> s = d.samples();
  ASSERT_EQ(s.size(), 3u);  // the corrupt one (its readings are good; its stamp is its read time), then lines 4 and 5
  EXPECT_EQ(s[0].t, R);
  EXPECT_EQ(s[1].t, R + 15 * ms);
  EXPECT_EQ(s[2].t, R + 20 * ms);
  EXPECT_EQ(d.live.stats().backwards_timestamps, 2u);
}

// Under the error policy a malformed line ends the stream after the samples before it, those of the same read()
// included (they were parsed first, and are stamped and queued before the problem is reported). Under the skip
// policy it is skipped, and the read's other lines are stamped as if it were not there.
TEST(ImuStreamReader, AMalformedLineEndsTheStreamAfterTheGoodLinesOfItsReadOrIsSkipped) {
  for (const bool too_long : {false, true}) {
    LiveSource::Options lo;
    lo.policy = BadInputPolicy::Error;
    DeviceFeed d(too_long ? "error-long.csv" : "error-malformed.csv", lo);
    constexpr TimeNs T = 7'000'000'000, R = 1'000'000'000'000, ms = 1'000'000;
    const std::string bad = too_long ? std::string(5000, '7') : std::string("7,0,0,zero,0,0,9.81");
    d.feed(device_lines({T, T + 5 * ms}) + bad + "\n" + device_lines({T + 10 * ms}), R);
    ASSERT_EQ(d.live.next().has_value(), true);
    ASSERT_EQ(d.live.next().has_value(), true);
    try {
      d.live.next();
      ADD_FAILURE() << "no error";
    } catch (const IoError& e) {  // (a problem of the stream's text, as a corrupt file's)
      EXPECT_NE(std::string(e.what()).find(d.file.string() + ":3: "), std::string::npos) << e.what();
    }
  }
  // Under the skip policy the read's good lines are stamped together, the device clock's offset from the latest of
  // them: 5 ms apart, the last one at the read time.
  DeviceFeed d("skip-malformed.csv");
  constexpr TimeNs T = 7'000'000'000, R = 1'000'000'000'000, ms = 1'000'000;
  d.feed(device_lines({T, T + 5 * ms}) + "7,0,0,zero,0,0,9.81\n" + device_lines({T + 10 * ms, T + 15 * ms}), R);
  const std::vector<ImuSample> s = d.samples();
  ASSERT_EQ(s.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(s[k].t, R - 15 * ms + 5 * ms * static_cast<TimeNs>(k)) << k;
  EXPECT_EQ(d.live.stats().malformed_lines, 1u);
}

// A device clock 1 % slow against the host's, read every second with a 1 ms delay for 40 s: the delay estimate
// forgets minima older than two 10 s windows, so the stamps stay within 0.25 s of the read times (the smallest delay
// ever seen would leave them 0.4 s behind by the end).
TEST(ImuStreamReader, TheDeviceClockIsFollowedWhenItDrifts) {
  DeviceFeed d("drift.csv");
  constexpr TimeNs R = 1'000'000'000'000, s1 = 1'000'000'000;
  for (TimeNs k = 0; k <= 40; ++k) d.feed(device_lines({k * 990'000'000}), R + k * s1 + 1'000'000);
  const std::vector<ImuSample> s = d.samples();
  ASSERT_EQ(s.size(), 41u);
  EXPECT_LT(std::abs(static_cast<double>(s.back().t - (R + 40 * s1))), 0.25e9);
}

TEST(ImuStreamReader, RangeAndGapProblemsAreCountedUnderSkipAndStopTheStreamUnderError) {
  const auto lines = [](TimeNs t0) {
    return fmt::format("{0},0,0,0,0,0,9.81\n{1},0,0,0,0,0,9.81\n{2},0,0,0,0,0,5000\n{3},0,0,0,0,0,9.81\n", t0,
                       t0 + 5'000'000, t0 + 10'000'000, t0 + 200'000'000);
  };
  ImuStreamReader::Options o;
  o.range.accel_m_s2 = 160.0;
  o.rate_hz = 200.0;
  {
    Fifo fifo("skip");
    ImuStreamReader reader(fifo.path.string(), o);
    LiveSource live(LiveSource::Options{});
    const std::string text = lines(now_ns());
    std::thread writer([&] { write_fifo(fifo.path, text); });
    EXPECT_TRUE(reader.run(live));
    writer.join();
    live.close();
    EXPECT_EQ(drain_imu(live).size(), 3u);  // the saturated one dropped; the one after the gap kept
    EXPECT_EQ(live.stats().imu_saturated, 1u);
    EXPECT_EQ(live.stats().imu_gaps, 1u);
  }
  {
    Fifo fifo("error");
    ImuStreamReader reader(fifo.path.string(), o);
    LiveSource::Options lo;
    lo.policy = BadInputPolicy::Error;
    LiveSource live(lo);
    const std::string text = lines(now_ns());
    std::thread writer([&] { write_fifo(fifo.path, text); });
    reader.run(live);
    writer.join();
    EXPECT_EQ(live.next().has_value(), true);
    EXPECT_EQ(live.next().has_value(), true);
    try {
      live.next();
      ADD_FAILURE() << "no error";
    } catch (const DataError& e) {
      EXPECT_NE(std::string(e.what()).find(fifo.path.string() + ":3: accelerometer"), std::string::npos) << e.what();
    }
  }
}

TEST(ImuStreamReader, InterruptEndsTheWaitForAWriterAtOnce) {
  Fifo fifo("interrupt");
  ImuStreamReader reader(fifo.path.string(), ImuStreamReader::Options{});
  LiveSource live(LiveSource::Options{});
  std::atomic<bool> returned{false};
  bool ended = true;
  std::thread t([&] {
    ended = reader.run(live);  // no writer ever opens the FIFO
    returned = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_FALSE(returned.load());
  const auto start = Clock::now();
  reader.interrupt();
  t.join();
  EXPECT_LT(Clock::now() - start, std::chrono::seconds(2));
  EXPECT_FALSE(ended);
}

// A serial device, here a pseudo-terminal: opened in the middle of the flow, so the bytes before the first newline
// (a line's tail) are dropped; its hang-up (the master closed, as a USB adapter unplugged) is an error, not an end.
TEST(ImuStreamReader, ASerialDeviceDropsTheFirstFragmentAndItsHangUpIsAnError) {
  const int master = ::posix_openpt(O_RDWR | O_NOCTTY);
  ASSERT_GE(master, 0);
  ASSERT_EQ(::grantpt(master), 0);
  ASSERT_EQ(::unlockpt(master), 0);
  const std::string slave = ::ptsname(master);
  ImuStreamReader reader(slave, ImuStreamReader::Options{});
  LiveSource live(LiveSource::Options{});
  std::string error;
  std::thread t([&] {
    try {
      reader.run(live);
    } catch (const IoError& e) {
      error = e.what();
    }
    live.close();  // (a reader that failed early leaves next() below no sample to wait for)
  });
  const TimeNs t0 = now_ns();
  const std::string text = fmt::format("0.1,0.02,9.81\n{},0,0,0,0,0,9.81\n{},0,0,0,0,0,9.81\n", t0, t0 + 5'000'000);
  ASSERT_EQ(::write(master, text.data(), text.size()), static_cast<ssize_t>(text.size()));
  // Both samples arrive (next() waits for them), then the device hangs up.
  const std::optional<Measurement> a = live.next(), b = live.next();
  ::close(master);
  t.join();
  EXPECT_NE(error.find(slave + ": the IMU device stopped after 2 lines"), std::string::npos) << error;
  ASSERT_TRUE(a && b);
  EXPECT_EQ(time_of(*a), t0);
  EXPECT_EQ(time_of(*b), t0 + 5'000'000);
  EXPECT_EQ(live.stats().problems(), 0u);  // the fragment is not a malformed line
}

TEST(ImuStreamReader, AMissingStreamOrAFolderIsAOneLineErrorNamingIt) {
  const fs::path missing = fs::temp_directory_path() / "rtslam_test_live_no_such_fifo";
  fs::remove_all(missing);
  try {
    ImuStreamReader r(missing.string(), ImuStreamReader::Options{});
    ADD_FAILURE() << "no error";
  } catch (const IoError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(missing.string() + ": cannot open the IMU stream", 0), 0u) << e.what();
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
  }
  EXPECT_THROW(ImuStreamReader(fs::temp_directory_path().string(), ImuStreamReader::Options{}), IoError);
  EXPECT_THROW(imu_stream_clock_from_string("gps", "--imu-clock"), ConfigError);
}

// --------------------------------------------------------------------------------------------------- LiveRigSource

/// A camera delivering 2x2 frames stamped on the steady clock every `period` until interrupted, or, as a V4L2
/// device does (`like_a_device`), forever: interrupt() does not end its wait for the next frame.
class FakeCamera final : public Source {
 public:
  explicit FakeCamera(std::chrono::milliseconds period, bool like_a_device = false)
      : period_(period), like_a_device_(like_a_device) {}
  std::optional<Measurement> next() override {
    std::unique_lock lock(mutex_);
    if (like_a_device_) {
      lock.unlock();
      std::this_thread::sleep_for(period_);
    } else if (cv_.wait_for(lock, period_, [&] { return stop_; })) {
      return std::nullopt;
    }
    ImageFrame f = image_at(now_ns());
    f.path = "camera#" + std::to_string(++frames_);
    return f;
  }
  const SourceStats& stats() const override { return stats_; }
  void interrupt() override {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
  }

 private:
  std::chrono::milliseconds period_;
  bool like_a_device_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
  int frames_ = 0;
  SourceStats stats_;
};

TEST(LiveRigSource, MergesTheCameraAndTheImuStreamInTimeOrderUntilTheImuStreamEnds) {
  Fifo fifo("rig");
  auto reader = std::make_unique<ImuStreamReader>(fifo.path.string(), ImuStreamReader::Options{});
  LiveRigSource rig(std::make_unique<FakeCamera>(std::chrono::milliseconds(50)), std::move(reader),
                    LiveSource::Options{});
  // 200 Hz for 0.6 s, each sample written when its time comes.
  std::thread writer([&] {
    const int fd = ::open(fifo.path.c_str(), O_WRONLY);
    ASSERT_GE(fd, 0);
    const auto start = Clock::now();
    for (int k = 0; k < 120; ++k) {
      std::this_thread::sleep_until(start + std::chrono::milliseconds(5 * k));
      const std::string line = fmt::format("{},0,0,0,0,0,9.81\n", now_ns());
      ASSERT_EQ(::write(fd, line.data(), line.size()), static_cast<ssize_t>(line.size()));
    }
    ::close(fd);
  });
  // Each sensor's measurements in time order, and each image after every IMU sample before its time (an image waits
  // for the sample that covers it); IMU samples later than an image may come before it (it reached the merge after
  // them: the inertial robot buffers them).
  std::size_t images = 0, imu = 0;
  TimeNs last_image = std::numeric_limits<TimeNs>::min(), last_imu = last_image;
  int unordered = 0, late_imu = 0;
  while (auto m = rig.next()) {
    const TimeNs t = time_of(*m);
    if (std::holds_alternative<ImageFrame>(*m)) {
      unordered += t <= last_image ? 1 : 0;
      last_image = t;
      ++images;
    } else {
      unordered += t <= last_imu ? 1 : 0;
      late_imu += t < last_image ? 1 : 0;
      last_imu = t;
      ++imu;
    }
  }
  writer.join();
  EXPECT_EQ(unordered, 0);
  EXPECT_EQ(late_imu, 0);
  EXPECT_EQ(imu, 120u);
  EXPECT_GE(images, 5u);  // about 12 in 0.6 s; a loaded machine may be late
  EXPECT_EQ(rig.stats().imu_samples, 120u);
  EXPECT_EQ(rig.stats().images, images);
}

TEST(LiveRigSource, InterruptStopsBothThreadsWhileTheImuStreamHasNoWriter) {
  Fifo fifo("rig_stop");
  auto reader = std::make_unique<ImuStreamReader>(fifo.path.string(), ImuStreamReader::Options{});
  // A camera that, like a device, delivers a frame every period whatever interrupt() says.
  auto rig = std::make_unique<LiveRigSource>(std::make_unique<FakeCamera>(std::chrono::milliseconds(20), true),
                                             std::move(reader), LiveSource::Options{});
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const auto start = Clock::now();
  rig->interrupt();
  std::size_t images = 0;
  while (auto m = rig->next()) images += std::holds_alternative<ImageFrame>(*m) ? 1 : 0;
  rig.reset();  // joins both threads
  EXPECT_LT(Clock::now() - start, std::chrono::seconds(2));
  EXPECT_LE(images, 30u);  // the images queued before the stop (none covered by an IMU)
}

}  // namespace
}  // namespace rtslam::io
