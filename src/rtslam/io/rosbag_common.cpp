// The ROS-free half of rosbag_source.hpp, compiled in every build: calibration paths and image encodings.
#include <filesystem>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "rtslam/core/error.hpp"
#include "rtslam/io/rosbag_source.hpp"

namespace rtslam::io {
namespace fs = std::filesystem;

Rig load_rig(const std::string& path, const std::vector<int>& cameras) {
  if (fs::is_directory(path)) {  // an EuRoC / ASL folder (or TUM-VI's export): R is the IMU
    const fs::path root = fs::is_directory(fs::path(path) / "mav0") ? fs::path(path) / "mav0" : fs::path(path);
    return load_euroc_folder_calibration(root.string(), cameras, FolderImu::IfPresent);
  }
  if (!fs::exists(path)) throw IoError(fmt::format("{}: calibration not found", path));
  const Rig all = load_calibration(path);
  Rig rig = all;
  rig.cameras.clear();
  for (int c : cameras) {
    if (c < 0 || static_cast<std::size_t>(c) >= all.cameras.size()) {
      throw ConfigError(fmt::format("{}: has no camera {} (it has {})", path, c, all.cameras.size()));
    }
    rig.cameras.push_back(all.cameras[static_cast<std::size_t>(c)]);
  }
  return rig;
}

namespace {

struct Encoding {
  const char* name;
  int channels;
  int conversion;  // cv::cvtColor code to grey, -1: already grey
};

// Bayer patterns: ROS names the 2x2 block from the top-left pixel, OpenCV from the second row and column (as
// cv_bridge maps them: rggb -> BG, bggr -> RG, gbrg -> GR, grbg -> GB). 8UC3 / 8UC4 are taken as BGR(A), OpenCV's
// order, as cv_bridge does.
constexpr Encoding kEncodings[] = {
    {"mono8", 1, -1},
    {"8UC1", 1, -1},
    {"rgb8", 3, cv::COLOR_RGB2GRAY},
    {"bgr8", 3, cv::COLOR_BGR2GRAY},
    {"8UC3", 3, cv::COLOR_BGR2GRAY},
    {"rgba8", 4, cv::COLOR_RGBA2GRAY},
    {"bgra8", 4, cv::COLOR_BGRA2GRAY},
    {"8UC4", 4, cv::COLOR_BGRA2GRAY},
    {"bayer_rggb8", 1, cv::COLOR_BayerBG2GRAY},
    {"bayer_bggr8", 1, cv::COLOR_BayerRG2GRAY},
    {"bayer_gbrg8", 1, cv::COLOR_BayerGR2GRAY},
    {"bayer_grbg8", 1, cv::COLOR_BayerGB2GRAY},
};

}  // namespace

std::string supported_ros_image_encodings() {
  std::string s;
  for (const Encoding& e : kEncodings) s += fmt::format("{}{}", s.empty() ? "" : ", ", e.name);
  return s;
}

cv::Mat grey_from_ros_image(const std::string& encoding, std::uint32_t width, std::uint32_t height, std::uint32_t step,
                            const std::uint8_t* data, std::size_t size, std::string* error) {
  const auto fail = [&](const std::string& message) {
    if (error != nullptr) *error = message;
    return cv::Mat();
  };
  const Encoding* enc = nullptr;
  for (const Encoding& e : kEncodings) {
    if (encoding == e.name) enc = &e;
  }
  if (enc == nullptr) {
    return fail(fmt::format("encoding '{}' is not supported (8-bit encodings only: {})", encoding,
                            supported_ros_image_encodings()));
  }
  constexpr std::uint32_t kMaxSide = 1u << 15;
  if (width == 0 || height == 0 || width > kMaxSide || height > kMaxSide) {
    return fail(fmt::format("image size {}x{} is empty or larger than {} px", width, height, kMaxSide));
  }
  const std::uint64_t row_bytes = std::uint64_t{width} * static_cast<std::uint64_t>(enc->channels);
  if (step < row_bytes) {
    return fail(fmt::format("step {} is less than width x channels = {} ({})", step, row_bytes, encoding));
  }
  if (data == nullptr || size != std::uint64_t{step} * height) {
    return fail(fmt::format("{} bytes of pixel data, step x height = {}", size, std::uint64_t{step} * height));
  }
  // cv::Mat does not write through this view: the const_cast only fits its constructor.
  const cv::Mat view(static_cast<int>(height), static_cast<int>(width), CV_8UC(enc->channels),
                     const_cast<std::uint8_t*>(data), step);
  cv::Mat grey;
  if (enc->conversion < 0) {
    grey = view.clone();
  } else {
    cv::cvtColor(view, grey, enc->conversion);
  }
  return grey;
}

}  // namespace rtslam::io
