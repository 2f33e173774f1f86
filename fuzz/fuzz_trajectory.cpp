// Fuzz target: the trajectory readers (io/trajectory_io.hpp) — TUM text, EuRoC state CSV (header variants, rtslam's
// covariance columns), KITTI poses — each forced and auto-detected. What a reader accepts must be valid
// (check_trajectory) and must survive its writer: TUM and CSV read back bit-identically (documented), KITTI to
// rounding (its rotation matrices are rebuilt from quaternions). Every accepted trajectory must also be writable
// as KITTI and read back (TUM and CSV accept quaternions 1e-2 off unit norm).
#include <cmath>

#include "fuzz_checks.hpp"
#include "fuzz_util.hpp"
#include "rtslam/io/trajectory_io.hpp"

using namespace rtslam;
using io::TrajectoryFormat;

namespace {

void check_same(const Trajectory& a, const Trajectory& b, bool exact) {
  FUZZ_CHECK(a.poses.size() == b.poses.size(), "round trip pose count");
  for (size_t i = 0; i < a.poses.size(); ++i) {
    const StampedPose& x = a.poses[i];
    const StampedPose& y = b.poses[i];
    FUZZ_CHECK(x.t == y.t && x.p_WR == y.p_WR, "round trip time/position");
    if (exact) {
      FUZZ_CHECK(x.q_WR.coeffs() == y.q_WR.coeffs(), "round trip quaternion");
      FUZZ_CHECK(x.v_WR == y.v_WR && x.gyro_bias == y.gyro_bias && x.accel_bias == y.accel_bias && x.cov == y.cov,
                 "round trip optional groups");
    } else {
      // KITTI: R -> nearest unit quaternion -> R -> quaternion, exact to rounding.
      FUZZ_CHECK(x.q_WR.normalized().angularDistance(y.q_WR.normalized()) < 1e-9, "round trip rotation");
    }
  }
}

void read_and_round_trip(const std::string& path, TrajectoryFormat format, const char* call) {
  Trajectory traj;
  if (!fuzz::expect_typed_errors(call, path, [&] { traj = io::read_trajectory(path, format); })) return;
  fuzz::check_trajectory(traj);
  if (format == TrajectoryFormat::Auto) return;
  const std::string copy = fuzz::scratch_dir() + "/written.txt";
  Trajectory back;
  const bool ok =
      fuzz::expect_typed_errors("write", copy, [&] {
        if (format == TrajectoryFormat::Tum) io::write_tum(copy, traj);
        if (format == TrajectoryFormat::EurocCsv) io::write_trajectory_csv(copy, traj);
        if (format == TrajectoryFormat::Kitti) io::write_kitti(copy, traj);
      }) &&
      fuzz::expect_typed_errors("read back", copy, [&] { back = io::read_trajectory(copy, format); });
  if (!ok) fuzz::finding(std::string(call) + ": an accepted trajectory does not write and read back");
  check_same(traj, back, format != TrajectoryFormat::Kitti);
  if (format == TrajectoryFormat::Kitti) return;
  Trajectory as_kitti;
  if (!fuzz::expect_typed_errors("write_kitti + read back", copy, [&] {
        io::write_kitti(copy, traj);
        as_kitti = io::read_trajectory(copy, TrajectoryFormat::Kitti);
      })) {
    fuzz::finding(std::string(call) + ": an accepted trajectory does not convert to KITTI");
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = fuzz::write_input("trajectory.txt", data, size);
  read_and_round_trip(path, TrajectoryFormat::Auto, "read_trajectory(auto)");
  read_and_round_trip(path, TrajectoryFormat::Tum, "read_trajectory(tum)");
  read_and_round_trip(path, TrajectoryFormat::EurocCsv, "read_trajectory(euroc)");
  read_and_round_trip(path, TrajectoryFormat::Kitti, "read_trajectory(kitti)");
  return 0;
}
