// Fuzz target: the live IMU stream's line reader (io/imu_stream.hpp), which reads whatever a driver, a serial port at
// the wrong baud rate or a pipe writes. The input is read as the stream (a file: the same code path as a FIFO's
// writer closing it), with each clock: the host clock (whose plausibility check refuses nearly every fuzzed time:
// bad input naming the file) and the device clock, under both policies. What reaches
// the consumer must be fit for the filter: finite readings within the sensor's range, strictly increasing times;
// every problem counted under Skip; under Error, a typed error naming the file.
#include <cstdint>
#include <optional>
#include <variant>

#include "fuzz_checks.hpp"
#include "fuzz_util.hpp"
#include "rtslam/io/imu_stream.hpp"
#include "rtslam/io/live_source.hpp"

using namespace rtslam;

namespace {

void read_stream(const std::string& path, io::ImuStreamClock clock, io::BadInputPolicy policy, const char* call) {
  io::ImuStreamReader::Options o;
  o.clock = clock;
  o.range.gyro_rad_s = 35.0;
  o.range.accel_m_s2 = 160.0;
  o.rate_hz = 200.0;
  io::LiveSource::Options lo;
  lo.policy = policy;
  lo.imu_capacity = 4096;  // more than the lines of an input (max_len 4096): none dropped for lack of room
  io::LiveSource live(lo);
  std::optional<io::ImuStreamReader> reader;
  if (!fuzz::expect_typed_errors(call, path, [&] { reader.emplace(path, o); })) return;
  bool ended = false;
  if (!fuzz::expect_typed_errors(call, path, [&] { ended = reader->run(live); })) return;
  FUZZ_CHECK(ended, "a file's end ends the stream");
  live.close();
  std::size_t samples = 0;
  std::optional<TimeNs> last;
  const bool drained = fuzz::expect_typed_errors(call, path, [&] {
    while (auto m = live.next()) {
      const auto* s = std::get_if<io::ImuSample>(&*m);
      FUZZ_CHECK(s != nullptr, "an IMU stream yields IMU samples only");
      FUZZ_CHECK(s->gyro.allFinite() && s->accel.allFinite(), "finite readings");
      FUZZ_CHECK(io::imu_range_problem(*s, o.range).empty(), "within range");
      FUZZ_CHECK(!last || s->t > *last, "strictly increasing times");
      last = s->t;
      ++samples;
    }
  });
  if (!drained) {
    FUZZ_CHECK(policy == io::BadInputPolicy::Error, "only the Error policy stops the stream");
    return;
  }
  const io::SourceStats& stats = live.stats();
  FUZZ_CHECK(stats.imu_samples == samples, "the yielded samples are counted");
  // Every line is a sample, a skipped problem, or blank / a comment / the header: never more samples and problems
  // (a gap is counted with the sample after it, which is kept) than lines.
  FUZZ_CHECK(samples + stats.problems() - stats.imu_gaps <= static_cast<std::size_t>(reader->lines()),
             "no line counted twice");
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("imu_stream.csv", data, size);
  for (const auto policy : {io::BadInputPolicy::Skip, io::BadInputPolicy::Error}) {
    read_stream(path, io::ImuStreamClock::Host, policy, "ImuStreamReader(host)");
    read_stream(path, io::ImuStreamClock::Device, policy, "ImuStreamReader(device)");
  }
  return 0;
}
