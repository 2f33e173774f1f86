#pragma once
// Helpers shared by the vision tests: dataset paths, image loading (OpenCV through io/codecs.hpp), synthetic textures.
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*
#include <opencv2/imgproc.hpp>

#include "rtslam/core/random.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/vision/image.hpp"
#include "rtslam/vision/simd.hpp"

namespace rtslam::vision::test {

inline std::string datasets_dir() { return std::string(RTSLAM_SOURCE_DIR) + "/../shared/datasets"; }

inline std::string monoslam_frame(int k) {
  char name[64];
  std::snprintf(name, sizeof(name), "/monoslam-davison/frames/rawoutput%04d.pgm", k);
  return datasets_dir() + name;
}

inline std::string euroc_cam0_dir() { return datasets_dir() + "/euroc-v101-static/mav0/cam0/data"; }

/// The sorted EuRoC cam0 frame paths (empty if the dataset is absent).
inline std::vector<std::string> euroc_frames() {
  std::vector<std::string> out;
  if (!std::filesystem::is_directory(euroc_cam0_dir())) return out;
  for (const auto& e : std::filesystem::directory_iterator(euroc_cam0_dir()))
    if (e.path().extension() == ".png") out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

inline Image from_mat(const cv::Mat& m) {
  Image img(m.cols, m.rows);
  for (int v = 0; v < m.rows; ++v)
    for (int u = 0; u < m.cols; ++u) img.at(u, v) = m.at<std::uint8_t>(v, u);
  return img;
}

inline cv::Mat to_mat(ImageView v) {
  cv::Mat m(v.height, v.width, CV_8UC1);
  for (int y = 0; y < v.height; ++y)
    for (int x = 0; x < v.width; ++x) m.at<std::uint8_t>(y, x) = v.at(x, y);
  return m;
}

/// Loads an 8-bit grey image; an empty Image if the file is missing or unreadable.
inline Image load_gray(const std::string& path) {
  if (!std::filesystem::exists(path)) return {};
  const cv::Mat m = io::codecs::imread(path, cv::IMREAD_GRAYSCALE);
  if (m.empty()) return {};
  return from_mat(m);
}

/// Uniform random pixels.
inline Image random_image(int w, int h, Rng& rng) {
  Image img(w, h);
  std::uniform_int_distribution<int> d(0, 255);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) img.at(u, v) = static_cast<std::uint8_t>(d(rng));
  return img;
}

/// Smooth random texture (white noise blurred by a Gaussian of sigma px, stretched to ~[20, 235]).
inline cv::Mat smooth_texture(int w, int h, double sigma, Rng& rng) {
  cv::Mat noise(h, w, CV_32F);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) noise.at<float>(v, u) = static_cast<float>(randn(rng));
  cv::Mat blurred;
  cv::GaussianBlur(noise, blurred, cv::Size(0, 0), sigma, sigma, cv::BORDER_REFLECT);
  cv::Scalar mean, sd;
  cv::meanStdDev(blurred, mean, sd);
  cv::Mat out;
  blurred.convertTo(out, CV_8U, 45.0 / sd[0], 128.0 - 45.0 * mean[0] / sd[0]);
  return out;
}

/// The SIMD levels this CPU runs, lowest first: scalar, then SSE2 and AVX2 when available.
inline std::vector<SimdLevel> simd_levels() {
  std::vector<SimdLevel> out;
  for (int l = 0; l <= static_cast<int>(best_simd_level()); ++l) out.push_back(static_cast<SimdLevel>(l));
  return out;
}

/// Selects a SIMD level for the lifetime of the guard, then restores the previous one.
class ScopedSimdLevel {
 public:
  explicit ScopedSimdLevel(SimdLevel level) : previous_(simd_level()) { set_simd_level(level); }
  ~ScopedSimdLevel() { set_simd_level(previous_); }
  ScopedSimdLevel(const ScopedSimdLevel&) = delete;
  ScopedSimdLevel& operator=(const ScopedSimdLevel&) = delete;

 private:
  SimdLevel previous_;
};

/// Bilinear sample of a float or 8-bit Mat (written here, independently of vision::sample_bilinear).
inline double bilinear(const cv::Mat& m, double x, double y) {
  x = std::clamp(x, 0.0, m.cols - 1.000001);
  y = std::clamp(y, 0.0, m.rows - 1.000001);
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const double fx = x - x0, fy = y - y0;
  auto at = [&](int xx, int yy) {
    return m.type() == CV_32F ? static_cast<double>(m.at<float>(yy, xx)) : static_cast<double>(m.at<std::uint8_t>(yy, xx));
  };
  return (1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x0 + 1, y0)) + fy * ((1 - fx) * at(x0, y0 + 1) + fx * at(x0 + 1, y0 + 1));
}

}  // namespace rtslam::vision::test
