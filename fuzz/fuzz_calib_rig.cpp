// Fuzz target: rtslam's own rig YAML (strict, docs/datasets.md), read by load_rig_yaml and load_calibration; what
// it accepts must be valid, and written by write_rig_yaml it must read back exactly (the documented round trip).
#include "fuzz_checks.hpp"
#include "fuzz_util.hpp"
#include "rtslam/io/calibration.hpp"

using namespace rtslam;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("rig.yaml", data, size);
  io::Rig rig;
  if (fuzz::expect_typed_errors("load_rig_yaml", path, [&] { rig = io::load_rig_yaml(path); })) {
    fuzz::check_rig(rig);
    const std::string copy = fuzz::scratch_dir() + "/rig-written.yaml";
    io::Rig back;
    if (!fuzz::expect_typed_errors("write_rig_yaml", copy, [&] { io::write_rig_yaml(copy, rig); }) ||
        !fuzz::expect_typed_errors("load_rig_yaml(written)", copy, [&] { back = io::load_rig_yaml(copy); })) {
      fuzz::finding("a rig that load_rig_yaml accepted does not write and read back");
    }
    fuzz::check_same_rig(rig, back);
  }
  if (fuzz::expect_typed_errors("load_calibration", path, [&] { rig = io::load_calibration(path); })) {
    fuzz::check_rig(rig);
  }
  return 0;
}
