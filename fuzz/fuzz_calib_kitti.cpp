// Fuzz target: KITTI odometry `calib.txt` (`PN:` lines of 12 numbers), read by load_kitti_calib for cameras 0 and 1.
#include "fuzz_checks.hpp"
#include "fuzz_util.hpp"
#include "rtslam/io/calibration.hpp"

using namespace rtslam;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("calib.txt", data, size);
  for (int camera : {0, 1}) {
    io::CameraCalibration cam;
    if (fuzz::expect_typed_errors("load_kitti_calib", path, [&] { cam = io::load_kitti_calib(path, camera); })) {
      fuzz::check_camera(cam, /*size_known=*/false);
    }
  }
  return 0;
}
