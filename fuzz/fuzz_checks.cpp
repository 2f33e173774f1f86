#include "fuzz_checks.hpp"

#include <cmath>

#include <fmt/format.h>

#include "fuzz_util.hpp"

namespace rtslam::fuzz {
namespace {

bool finite(double x) { return std::isfinite(x); }

void check_rigid(const Eigen::Isometry3d& T, const std::string& what) {
  FUZZ_CHECK(T.matrix().allFinite(), what);
  const Eigen::Matrix3d R = T.linear();
  const double err = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  FUZZ_CHECK(err < 1e-6 && R.determinant() > 0.0, fmt::format("{}: rotation error {}", what, err));
}

}  // namespace

void check_camera(const io::CameraCalibration& cam, bool size_known) {
  const std::string what = "camera " + cam.name;
  if (size_known) FUZZ_CHECK(cam.width > 0 && cam.height > 0, what);
  FUZZ_CHECK(cam.fx > 0 && cam.fy > 0 && finite(cam.fx) && finite(cam.fy), what);
  FUZZ_CHECK(finite(cam.cx) && finite(cam.cy), what);
  FUZZ_CHECK(cam.rate_hz >= 0 && finite(cam.rate_hz), what);
  FUZZ_CHECK(static_cast<int>(cam.distortion_coeffs.size()) == io::distortion_coefficient_count(cam.distortion), what);
  for (double k : cam.distortion_coeffs) FUZZ_CHECK(finite(k), what);
  check_rigid(cam.T_RS, what + " T_RS");
}

void check_imu(const io::ImuCalibration& imu) {
  FUZZ_CHECK(imu.rate_hz > 0 && finite(imu.rate_hz), "imu rate_hz");
  FUZZ_CHECK(imu.gyro_noise_density > 0 && finite(imu.gyro_noise_density), "imu gyro_noise_density");
  FUZZ_CHECK(imu.accel_noise_density > 0 && finite(imu.accel_noise_density), "imu accel_noise_density");
  FUZZ_CHECK(imu.gyro_random_walk >= 0 && finite(imu.gyro_random_walk), "imu gyro_random_walk");
  FUZZ_CHECK(imu.accel_random_walk >= 0 && finite(imu.accel_random_walk), "imu accel_random_walk");
  if (imu.gyro_saturation) FUZZ_CHECK(*imu.gyro_saturation > 0 && finite(*imu.gyro_saturation), "gyro_saturation");
  if (imu.accel_saturation) FUZZ_CHECK(*imu.accel_saturation > 0 && finite(*imu.accel_saturation), "accel_saturation");
  check_rigid(imu.T_RS, "imu T_RS");
}

void check_rig(const io::Rig& rig) {
  for (const auto& c : rig.cameras) check_camera(c);
  if (rig.imu) check_imu(*rig.imu);
}

void check_trajectory(const Trajectory& traj) {
  for (size_t i = 0; i < traj.poses.size(); ++i) {
    const StampedPose& p = traj.poses[i];
    const std::string what = fmt::format("{} pose {}", traj.source, i);
    FUZZ_CHECK(p.p_WR.allFinite() && p.q_WR.coeffs().allFinite(), what);
    FUZZ_CHECK(std::abs(p.q_WR.norm() - 1.0) < 1e-2, what);
    if (traj.has_timestamps && i > 0) FUZZ_CHECK(p.t > traj.poses[i - 1].t, what);
    if (p.v_WR) FUZZ_CHECK(p.v_WR->allFinite(), what);
    if (p.gyro_bias) FUZZ_CHECK(p.gyro_bias->allFinite(), what);
    if (p.accel_bias) FUZZ_CHECK(p.accel_bias->allFinite(), what);
    if (p.cov) FUZZ_CHECK(p.cov->allFinite() && *p.cov == p.cov->transpose(), what);
  }
}

void check_same_rig(const io::Rig& a, const io::Rig& b) {
  FUZZ_CHECK(a.cameras.size() == b.cameras.size() && a.t_d == b.t_d && a.imu.has_value() == b.imu.has_value(),
             "rig round trip");
  for (size_t i = 0; i < a.cameras.size(); ++i) {
    const auto& x = a.cameras[i];
    const auto& y = b.cameras[i];
    FUZZ_CHECK(x.name == y.name, fmt::format("camera {} name '{}' read back as '{}'", i, x.name, y.name));
    FUZZ_CHECK(x.width == y.width && x.height == y.height && x.rate_hz == y.rate_hz && x.fx == y.fx &&
                   x.fy == y.fy && x.cx == y.cx && x.cy == y.cy && x.distortion == y.distortion &&
                   x.distortion_coeffs == y.distortion_coeffs && x.T_RS.matrix() == y.T_RS.matrix(),
               fmt::format("camera {} round trip", i));
  }
  if (a.imu) {
    const auto& x = *a.imu;
    const auto& y = *b.imu;
    FUZZ_CHECK(x.name == y.name, fmt::format("imu name '{}' read back as '{}'", x.name, y.name));
    FUZZ_CHECK(x.rate_hz == y.rate_hz && x.gyro_noise_density == y.gyro_noise_density &&
                   x.gyro_random_walk == y.gyro_random_walk && x.accel_noise_density == y.accel_noise_density &&
                   x.accel_random_walk == y.accel_random_walk && x.gyro_saturation == y.gyro_saturation &&
                   x.accel_saturation == y.accel_saturation && x.T_RS.matrix() == y.T_RS.matrix(),
               "imu round trip");
  }
}

}  // namespace rtslam::fuzz
