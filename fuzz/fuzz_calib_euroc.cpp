// Fuzz target: EuRoC/ASL `sensor.yaml` (camera and IMU; `%YAML:1.0` header, `!!opencv-matrix` T_BS), read by
// load_euroc_camera, load_euroc_imu and load_calibration (which picks the loader from the content).
#include "fuzz_checks.hpp"
#include "fuzz_util.hpp"
#include "rtslam/io/calibration.hpp"

using namespace rtslam;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("cam0/sensor.yaml", data, size);
  io::CameraCalibration cam;
  std::vector<std::string> warnings;
  if (fuzz::expect_typed_errors("load_euroc_camera", path, [&] { cam = io::load_euroc_camera(path, &warnings); })) {
    fuzz::check_camera(cam);
  }
  io::ImuCalibration imu;
  if (fuzz::expect_typed_errors("load_euroc_imu", path, [&] { imu = io::load_euroc_imu(path); })) {
    fuzz::check_imu(imu);
  }
  io::Rig rig;
  if (fuzz::expect_typed_errors("load_calibration", path, [&] { rig = io::load_calibration(path); })) {
    fuzz::check_rig(rig);
  }
  return 0;
}
