// Fuzz target: the dataset lists, read by open_dataset from small dataset folders built once in the scratch folder
// and drained. The first input byte chooses the dataset, the rest is its list:
//   'e'  EuRoC: `cam0/data.csv` and `imu0/data.csv` (`t[ns],filename` / `t[ns],w xyz,a xyz`; both get the list)
//   't'  TUM: `rgb.txt` (`t[s] path`)
//   'i'  image folder: `times.txt` (`t[s]` lines paired with the sorted images, or `t[s] name` lines)
//   'k'  KITTI: `times.txt` (`t[s]` lines)
//   any other byte: the dataset (byte mod 4) in that order.
// (One dataset per run keeps the target fast; scripts/fuzz.sh prefixes the dataset seeds with their letter.)
// Each opens with bad_input = error (a typed error naming a file of the dataset, or a clean stream) and, if that
// throws, with bad_input = skip (the problems are counted, the stream goes on). The stream must be time-ordered,
// with finite IMU samples and 8-bit grey images of the calibrated size.
//
// Images the lists can name: 1.png and 2.png (8x6, valid), 3.png (4x4: the wrong size), 4.png (not an image), and
// KITTI's 000000.png, 000001.png.
#include <cstring>
#include <filesystem>
#include <limits>
#include <variant>

#include <opencv2/imgcodecs.hpp>

#include "fuzz_util.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/io/dataset.hpp"

using namespace rtslam;
namespace fs = std::filesystem;

namespace {

constexpr int kWidth = 8;
constexpr int kHeight = 6;

const char* kEurocCamera = R"(%YAML:1.0
sensor_type: camera
T_BS:
  cols: 4
  rows: 4
  data: [1, 0, 0, 0.05, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
rate_hz: 20
resolution: [8, 6]
camera_model: pinhole
intrinsics: [10, 10, 4, 3]
distortion_model: radial-tangential
distortion_coefficients: [-0.28, 0.07, 0.0002, 0.00002]
)";

const char* kEurocImu = R"(%YAML:1.0
sensor_type: imu
T_BS:
  cols: 4
  rows: 4
  data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
rate_hz: 200
gyroscope_noise_density: 1.6968e-04
gyroscope_random_walk: 1.9393e-05
accelerometer_noise_density: 2.0000e-3
accelerometer_random_walk: 3.0000e-3
)";

const char* kRig = R"(cameras:
  - name: cam0
    width: 8
    height: 6
    rate_hz: 20
    intrinsics: [10, 10, 4, 3]
)";

void write_images(const std::string& dir) {
  fs::create_directories(dir);
  cv::imwrite(dir + "/1.png", cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(10)));
  cv::imwrite(dir + "/2.png", cv::Mat(kHeight, kWidth, CV_8UC3, cv::Scalar(10, 200, 30)));
  cv::imwrite(dir + "/3.png", cv::Mat(4, 4, CV_8UC1, cv::Scalar(1)));
  fuzz::write_input(fs::path(dir).lexically_relative(fuzz::scratch_dir()).string() + "/4.png", "not a PNG");
}

struct Layout {
  const char* kind;
  std::string root;                // the dataset folder (every error must name a file in it)
  std::vector<std::string> lists;  // relative paths that receive the input
};

std::vector<Layout> g_layouts;

void build_datasets() {
  const std::string s = fuzz::scratch_dir();
  fuzz::write_input("euroc/mav0/cam0/sensor.yaml", kEurocCamera);
  fuzz::write_input("euroc/mav0/imu0/sensor.yaml", kEurocImu);
  write_images(s + "/euroc/mav0/cam0/data");
  g_layouts.push_back({"euroc", s + "/euroc", {"mav0/cam0/data.csv", "mav0/imu0/data.csv"}});
  fuzz::write_input("tum/calibration.yaml", kRig);
  write_images(s + "/tum/rgb");
  g_layouts.push_back({"tum", s + "/tum", {"rgb.txt"}});
  fuzz::write_input("images/calibration.yaml", kRig);
  write_images(s + "/images/frames");
  g_layouts.push_back({"images", s + "/images", {"times.txt"}});
  const std::string seq = s + "/kitti/sequences/00";
  fs::create_directories(seq + "/image_0");
  cv::imwrite(seq + "/image_0/000000.png", cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(10)));
  cv::imwrite(seq + "/image_0/000001.png", cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(20)));
  fuzz::write_input("kitti/sequences/00/calib.txt",
                    "P0: 10 0 4 0 0 10 3 0 0 0 1 0\nP1: 10 0 4 -5 0 10 3 0 0 0 1 0\n");
  g_layouts.push_back({"kitti", seq, {"times.txt"}});
}

void check_stream(io::Dataset& ds) {
  TimeNs last = std::numeric_limits<TimeNs>::min();
  for (int n = 0;; ++n) {
    FUZZ_CHECK(n < 100000, "the stream does not end");
    const auto m = ds.source->next();
    if (!m) break;
    const TimeNs t = io::time_of(*m);
    FUZZ_CHECK(t >= last, "the stream goes back in time");
    last = t;
    if (const auto* s = std::get_if<io::ImuSample>(&*m)) {
      FUZZ_CHECK(s->gyro.allFinite() && s->accel.allFinite(), "non-finite IMU sample");
    } else {
      const auto& f = std::get<io::ImageFrame>(*m);
      FUZZ_CHECK(f.image.type() == CV_8UC1 && f.image.cols == kWidth && f.image.rows == kHeight,
                 "image of the wrong type or size: " + f.path);
      FUZZ_CHECK(f.camera == 0, "camera index");
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet_logs();
  rtslam::io::codecs::load_plugin();  // its images' decoders (a missing plugin stops the target here)
  build_datasets();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const char* kinds = "etik";
  const char* chosen = std::strchr(kinds, static_cast<char>(data[0]));
  const Layout& l = g_layouts[chosen && data[0] ? static_cast<std::size_t>(chosen - kinds) : data[0] % 4];
  for (const auto& rel : l.lists) {
    fuzz::write_input((fs::path(l.root) / rel).lexically_relative(fuzz::scratch_dir()).string(), data + 1, size - 1);
  }
  const std::string spec = std::string(l.kind) + ":" + l.root;
  for (const auto policy : {io::BadInputPolicy::Error, io::BadInputPolicy::Skip}) {
    io::DatasetOptions o;
    o.bad_input = policy;
    const bool clean = fuzz::expect_typed_errors("open_dataset + next", l.root, [&] {
      io::Dataset ds = io::open_dataset(spec, o);
      check_stream(ds);
    });
    if (clean) break;  // skip would see the same stream
  }
  return 0;
}
