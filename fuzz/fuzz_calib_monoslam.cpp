// Fuzz target: MonoSLAM / SceneLib `camera.json` (nlohmann::json), read by load_monoslam_camera and by
// load_calibration (chosen by the .json extension).
#include "fuzz_checks.hpp"
#include "fuzz_util.hpp"
#include "rtslam/io/calibration.hpp"

using namespace rtslam;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("camera.json", data, size);
  io::CameraCalibration cam;
  if (fuzz::expect_typed_errors("load_monoslam_camera", path, [&] { cam = io::load_monoslam_camera(path); })) {
    fuzz::check_camera(cam);
  }
  io::Rig rig;
  if (fuzz::expect_typed_errors("load_calibration", path, [&] { rig = io::load_calibration(path); })) {
    fuzz::check_rig(rig);
  }
  return 0;
}
