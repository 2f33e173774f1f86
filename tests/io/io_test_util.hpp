#pragma once
// Helpers for the io tests: a per-test temporary directory, small file writers, and dataset paths.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "rtslam/io/calibration.hpp"
#include "support/temp_dir.hpp"

namespace rtslam::io::test {

/// A fresh directory under the system temp dir, removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = ::rtslam::support::fresh_temp_dir("io", std::string(info->test_suite_name()) + "_" + info->name());
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string operator/(const std::string& rel) const { return (path_ / rel).string(); }
  std::string str() const { return path_.string(); }

 private:
  std::filesystem::path path_;
};

inline void write_text(const std::string& path, const std::string& text) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream out(path);
  out << text;
}

inline std::string read_text(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

/// The small EuRoC-like IMU of the io tests: 200 Hz, EuRoC-order noise densities and walks.
inline ImuCalibration small_imu() {
  ImuCalibration imu;
  imu.rate_hz = 200;
  imu.gyro_noise_density = 1.7e-4;
  imu.gyro_random_walk = 2e-5;
  imu.accel_noise_density = 2e-3;
  imu.accel_random_walk = 3e-3;
  return imu;
}

/// A 64x48 pinhole camera at 20 Hz (f 50 px, centred), without distortion.
inline CameraCalibration small_camera(const std::string& name = "cam0") {
  CameraCalibration cam;
  cam.name = name;
  cam.width = 64;
  cam.height = 48;
  cam.rate_hz = 20;
  cam.fx = cam.fy = 50;
  cam.cx = 32;
  cam.cy = 24;
  return cam;
}

inline std::string euroc_dir() { return RTSLAM_SOURCE_DIR "/../shared/datasets/euroc-v101-static"; }
inline std::string monoslam_dir() { return RTSLAM_SOURCE_DIR "/../shared/datasets/monoslam-davison"; }

}  // namespace rtslam::io::test

/// Expects `statement` to throw `type` whose what() contains `needle`.
#define EXPECT_THROW_WITH(statement, type, needle)                                                  \
  do {                                                                                              \
    try {                                                                                           \
      statement;                                                                                    \
      ADD_FAILURE() << "expected " #type " containing '" << (needle) << "'";                        \
    } catch (const type& e) {                                                                       \
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << "message: " << e.what(); \
    }                                                                                               \
  } while (false)
