#pragma once
// Sensor calibration as plain data (no camera-model classes), and loaders for the calibration files users have:
// EuRoC `sensor.yaml` (camera and IMU), Kalibr `camchain.yaml` / `imu.yaml`, MonoSLAM `camera.json` and rtslam's
// own rig YAML (format in docs/datasets.md).
//
// Extrinsics are always stored as T_RS: the sensor frame S expressed in the robot frame R (p_R = T_RS * p_S). On
// EuRoC-style rigs R is the IMU body frame. Conventions are chosen by key name, never guessed:
//   EuRoC `T_BS`             is T_RS (B = body = IMU on EuRoC);
//   Kalibr `T_cam_imu`       is T_SR and is inverted on load; without it (a cameras-only calibration) R is cam0 and
//                            `T_cn_cnm1` (camera n−1 in camera n) chains each camera to the previous one;
//   Kalibr imu.yaml `T_i_b`  is T_IB (IMU in body), unused when the IMU is R;
//   rtslam YAML `T_RS`       is T_RS.
// A rotation that is not orthonormal (|RᵀR − I| ≥ 1e-3 or det < 0) is a ConfigError naming the file and key (from
// 1e-6, a matrix written with few decimals, the nearest rotation is used; a camera's gets a warning); a
// camera–robot translation above 0.5 m is a warning (logged and kept in Rig::warnings): an inverted or
// wrong-unit transform is the classic user mistake.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <yaml-cpp/yaml.h>

#include "rtslam/core/time.hpp"
#include "rtslam/io/image_header.hpp"  // kMaxImageSide, kMaxImagePixels: the largest camera accepted

namespace rtslam::io {

/// Lens distortion models (formulas in MATH.md):
///  None;  RadTan (Kalibr radtan / EuRoC radial-tangential): k1 k2 p1 p2;
///  Equidistant (Kalibr equidistant / fisheye): k1 k2 k3 k4;
///  MonoSlamOneParam: kappa [px^-2], r_d = r_u / sqrt(1 + 2 kappa r_u^2), radii in pixels about (cx, cy).
enum class DistortionModel { None, RadTan, Equidistant, MonoSlamOneParam };

/// Name used in files ("none", "radtan", "equidistant", "monoslam_one_param").
std::string to_string(DistortionModel model);
/// Accepts our names and the aliases of EuRoC/Kalibr/OpenCV ("radial-tangential", "plumb_bob", "fisheye", ...);
/// throws ConfigError naming `where` and the value for an unknown model.
DistortionModel distortion_model_from_string(const std::string& name, const std::string& where);
/// Number of coefficients the model takes (0, 4, 4, 1).
int distortion_coefficient_count(DistortionModel model);

struct CameraCalibration {
  std::string name;      // "cam0", ...
  int width = 0;         // px
  int height = 0;        // px
  double rate_hz = 0.0;  // nominal frame rate (0 = unknown)
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;  // px
  DistortionModel distortion = DistortionModel::None;
  std::vector<double> distortion_coeffs;  // distortion_coefficient_count(distortion) values
  Eigen::Isometry3d T_RS = Eigen::Isometry3d::Identity();

  // The field of view (deg) a focal length may imply across the image (check_camera_calibration): outside it the
  // number is a unit slip or a swapped key, not a lens.
  static constexpr double kMinFovDeg = 0.5, kMaxFovDeg = 175.0;
};

struct ImuCalibration {
  std::string name = "imu0";
  double rate_hz = 0.0;
  double gyro_noise_density = 0.0;   // rad/s/sqrt(Hz)   (white noise)
  double gyro_random_walk = 0.0;     // rad/s^2/sqrt(Hz) (bias diffusion)
  double accel_noise_density = 0.0;  // m/s^2/sqrt(Hz)   (white noise)
  double accel_random_walk = 0.0;    // m/s^3/sqrt(Hz)   (bias diffusion)
  std::optional<double> gyro_saturation;   // rad/s, when known
  std::optional<double> accel_saturation;  // m/s^2, when known
  Eigen::Isometry3d T_RS = Eigen::Isometry3d::Identity();
};

struct Rig {
  std::vector<CameraCalibration> cameras;
  std::optional<ImuCalibration> imu;
  TimeNs t_d = 0;                     // time offset: t_imu = t_cam + t_d (Kalibr timeshift_cam_imu)
  std::vector<std::string> warnings;  // suspicious but accepted values (e.g. a camera 0.5 m from the IMU)
  bool r_is_imu = false;              // R is the IMU: the cameras' T_RS are relative to it (an IMU–camera
                                      // calibration, a rig with its IMU, a dataset's rig with an IMU); false: R is
                                      // cam0 or a body frame the file does not relate to an IMU
};

/// EuRoC camera `sensor.yaml` (the `%YAML:1.0` first line is accepted). `name` defaults to the folder name.
CameraCalibration load_euroc_camera(const std::string& path, std::vector<std::string>* warnings = nullptr);
/// EuRoC IMU `sensor.yaml`.
ImuCalibration load_euroc_imu(const std::string& path);

/// Kalibr camchain.yaml (every camN with T_cam_imu; or none with it, a cameras-only calibration: R is cam0, the others
/// chained by T_cn_cnm1), plus optionally Kalibr's imu.yaml (the `imu0:` block of a camchain-imucam result or a flat
/// input imu.yaml; refused with a cameras-only camchain, whose cameras are not placed relative to the IMU).
Rig load_kalibr(const std::string& camchain_path, const std::string& imu_path = "");
ImuCalibration load_kalibr_imu(const std::string& path);

/// MonoSLAM / SceneLib `camera.json`. SceneLib's camera frame is x left, y up, z forward; our camera (sensor) frame
/// is x right, y down, z forward. The returned T_RS has rotation R = diag(−1, −1, 1), so that the robot frame R is
/// SceneLib's camera frame and MonoSLAM's initial state (init/initial_state.json) applies to the robot as is.
/// The rate is the file's `fps` (25 for the Davison sequence, whose README says 30: override with the rate option).
CameraCalibration load_monoslam_camera(const std::string& path);

/// KITTI odometry `calib.txt`: the `P<camera>:` line, the 3x4 projection matrix P_N = K [I | t_N] of the
/// rectified camera N (12 numbers, row-major). Returns the intrinsics (no distortion: KITTI images are rectified)
/// and T_RS with R = camera 0 (translation -t_N: camera N sits at x = P[3] / -fx from camera 0). The image size and
/// rate are not in the file: width, height and rate_hz are 0 (the KITTI reader takes them from the images).
CameraCalibration load_kitti_calib(const std::string& path, int camera);

/// What load_euroc_folder_calibration does with the IMU's calibration: leaves it out, reads it when its file exists,
/// or requires it (an inertial run).
enum class FolderImu { Skip, IfPresent, Required };

/// The calibration of an EuRoC-format folder `mav0` (the one holding camN/ and imu0/) for the cameras `cameras`:
/// EuRoC's camN/sensor.yaml and imu0/sensor.yaml (R = the IMU: T_RS(cam) = T_BI⁻¹ T_BC with EuRoC's body frame B);
/// or, when none of those camera files exists and a `dso/camchain.yaml` lies beside `mav0` (TUM-VI's EuRoC-format
/// export has no sensor.yaml), that Kalibr camchain with `dso/imu_config.yaml` (Kalibr's imu.yaml) for the IMU.
/// `mav0` may also be the folder holding mav0/ and dso/, or the dso/ folder itself.
/// Throws IoError (a file missing, naming it) or ConfigError (a camera the calibration does not have, bad values).
Rig load_euroc_folder_calibration(const std::string& mav0, const std::vector<int>& cameras, FolderImu imu);

/// rtslam's own rig YAML (strict: unknown keys are errors). Format in docs/datasets.md.
Rig load_rig_yaml(const std::string& path);
/// Writes a rig in rtslam's own YAML format (read back exactly by load_rig_yaml).
void write_rig_yaml(const std::string& path, const Rig& rig);

/// Any of the above by content: .json -> MonoSLAM; YAML with `cameras:` -> rtslam; `cam0:` -> Kalibr camchain;
/// `sensor_type: camera|imu` -> EuRoC sensor.yaml; `imu0:` or `accelerometer_noise_density` -> Kalibr imu.yaml.
Rig load_calibration(const std::string& path);

/// Throws ConfigError naming `where`, the key, the value and the bound unless the camera is plausible: image sides
/// in [1, kMaxImageSide] and at most kMaxImagePixels pixels; fx, fy > 0 giving a field of view in
/// [kMinFovDeg, kMaxFovDeg] across the image (fov = 2 atan(side / 2f)), fx / fy in [0.25, 4]; the principal point
/// inside the image ([0, width] x [0, height]); rate_hz 0 (unknown) or in [1e-3, 1e5] Hz; the distortion model's
/// number of coefficients, each finite and within ±1e3. Every loader runs it.
void check_camera_calibration(const CameraCalibration& cam, const std::string& where);

/// Validates the rotation part of T (named `key` in `where`) and warns when |t| > 0.5 m; throws ConfigError.
void check_extrinsic(const Eigen::Matrix4d& T, const std::string& where, const std::string& key,
                     std::vector<std::string>* warnings, bool warn_far = true);

/// Loads a YAML file, accepting OpenCV/EuRoC's `%YAML:1.0` header and `!!opencv-matrix` tags. Throws IoError
/// (missing/unreadable) or ConfigError (malformed, naming the line).
YAML::Node load_yaml_lenient(const std::string& path);

}  // namespace rtslam::io
