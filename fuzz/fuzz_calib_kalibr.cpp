// Fuzz target: Kalibr `camchain.yaml` (camN blocks, T_cam_imu inverted on load, timeshift_cam_imu) and `imu.yaml`
// (flat or under `imu0:`), read by load_kalibr (camchain alone, and with the same file as its imu.yaml),
// load_kalibr_imu and load_calibration.
#include "fuzz_checks.hpp"
#include "fuzz_util.hpp"
#include "rtslam/io/calibration.hpp"

using namespace rtslam;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("camchain.yaml", data, size);
  io::Rig rig;
  if (fuzz::expect_typed_errors("load_kalibr", path, [&] { rig = io::load_kalibr(path); })) fuzz::check_rig(rig);
  if (fuzz::expect_typed_errors("load_kalibr(imu)", path, [&] { rig = io::load_kalibr(path, path); })) {
    fuzz::check_rig(rig);
  }
  io::ImuCalibration imu;
  if (fuzz::expect_typed_errors("load_kalibr_imu", path, [&] { imu = io::load_kalibr_imu(path); })) {
    fuzz::check_imu(imu);
  }
  if (fuzz::expect_typed_errors("load_calibration", path, [&] { rig = io::load_calibration(path); })) {
    fuzz::check_rig(rig);
  }
  return 0;
}
