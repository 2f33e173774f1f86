#include "rtslam/io/calibration.hpp"

#include <gtest/gtest.h>

#include <filesystem>

#include "io_test_util.hpp"
#include "rtslam/core/error.hpp"

namespace rtslam::io {
namespace {

using test::TempDir;
using test::read_text;
using test::write_text;

std::string euroc_cam0() { return test::euroc_dir() + "/mav0/cam0/sensor.yaml"; }

#define SKIP_WITHOUT_EUROC() \
  if (!std::filesystem::exists(euroc_cam0())) GTEST_SKIP() << "dataset euroc-v101-static not found"

// Kalibr's camchain for the EuRoC rig (cam0), as published with the dataset: T_cam_imu = T_SR.
const char* kKalibrCamchain = R"(cam0:
  T_cam_imu:
  - [0.01486554298177, 0.99955725006709, -0.02577444693258, 0.06522290953553]
  - [-0.99988093700141, 0.01496721332464, 0.00375618835797, -0.02070638549372]
  - [0.00414029679422, 0.02571552994787, 0.99966072717832, -0.00805460885664]
  - [0.0, 0.0, 0.0, 1.0]
  cam_overlaps: []
  camera_model: pinhole
  distortion_coeffs: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
  distortion_model: radtan
  intrinsics: [458.654, 457.296, 367.215, 248.375]
  resolution: [752, 480]
  rostopic: /cam0/image_raw
  timeshift_cam_imu: 0.0015
)";

TEST(Calibration, LoadsEurocCameraSensorYaml) {
  SKIP_WITHOUT_EUROC();
  std::vector<std::string> warnings;
  const CameraCalibration cam = load_euroc_camera(euroc_cam0(), &warnings);
  EXPECT_EQ(cam.name, "cam0");
  EXPECT_EQ(cam.width, 752);
  EXPECT_EQ(cam.height, 480);
  EXPECT_DOUBLE_EQ(cam.rate_hz, 20.0);
  EXPECT_DOUBLE_EQ(cam.fx, 458.654);
  EXPECT_DOUBLE_EQ(cam.fy, 457.296);
  EXPECT_DOUBLE_EQ(cam.cx, 367.215);
  EXPECT_DOUBLE_EQ(cam.cy, 248.375);
  EXPECT_EQ(cam.distortion, DistortionModel::RadTan);
  ASSERT_EQ(cam.distortion_coeffs.size(), 4u);
  EXPECT_DOUBLE_EQ(cam.distortion_coeffs[0], -0.28340811);
  EXPECT_DOUBLE_EQ(cam.distortion_coeffs[3], 1.76187114e-05);
  // T_BS row-major: row 0 = [0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975].
  EXPECT_DOUBLE_EQ(cam.T_RS.matrix()(0, 1), -0.999880929698);
  EXPECT_DOUBLE_EQ(cam.T_RS.translation().x(), -0.0216401454975);
  EXPECT_DOUBLE_EQ(cam.T_RS.translation().y(), -0.064676986768);
  EXPECT_TRUE(warnings.empty());
}

TEST(Calibration, LoadsEurocImuSensorYaml) {
  SKIP_WITHOUT_EUROC();
  const ImuCalibration imu = load_euroc_imu(test::euroc_dir() + "/mav0/imu0/sensor.yaml");
  EXPECT_DOUBLE_EQ(imu.rate_hz, 200.0);
  EXPECT_DOUBLE_EQ(imu.gyro_noise_density, 1.6968e-04);
  EXPECT_DOUBLE_EQ(imu.gyro_random_walk, 1.9393e-05);
  EXPECT_DOUBLE_EQ(imu.accel_noise_density, 2.0e-3);
  EXPECT_DOUBLE_EQ(imu.accel_random_walk, 3.0e-3);
  EXPECT_TRUE(imu.T_RS.isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_FALSE(imu.gyro_saturation.has_value());
  // Loading an IMU file as a camera is an error naming the sensor type.
  EXPECT_THROW_WITH(load_euroc_camera(test::euroc_dir() + "/mav0/imu0/sensor.yaml"), ConfigError, "expected 'camera'");
}

TEST(Calibration, EurocAndKalibrFilesGiveTheSameTRS) {
  SKIP_WITHOUT_EUROC();
  TempDir dir;
  write_text(dir / "camchain.yaml", kKalibrCamchain);
  const Rig kalibr = load_kalibr(dir / "camchain.yaml");
  const CameraCalibration euroc = load_euroc_camera(euroc_cam0());
  ASSERT_EQ(kalibr.cameras.size(), 1u);
  const Eigen::Matrix4d diff = kalibr.cameras[0].T_RS.matrix() - euroc.T_RS.matrix();
  // The two published files were rounded separately: their entries agree to ~1e-8 (e.g. R(0,1) = -0.999880929698 in
  // sensor.yaml vs -0.99988093700141 in the camchain), far below any inversion or convention error (~0.1).
  EXPECT_LT(diff.cwiseAbs().maxCoeff(), 5e-8) << "\n" << kalibr.cameras[0].T_RS.matrix() << "\n" << euroc.T_RS.matrix();
  // Not the un-inverted matrix: T_cam_imu's translation differs from T_BS's.
  EXPECT_GT((kalibr.cameras[0].T_RS.translation() - Eigen::Vector3d(0.06522290953553, -0.02070638549372,
                                                                      -0.00805460885664)).norm(), 0.05);
  EXPECT_DOUBLE_EQ(kalibr.cameras[0].fx, euroc.fx);
  EXPECT_EQ(kalibr.cameras[0].distortion, euroc.distortion);
  EXPECT_EQ(kalibr.cameras[0].distortion_coeffs, euroc.distortion_coeffs);
  EXPECT_EQ(kalibr.t_d, 1'500'000);
  // Auto-detection picks the same loader.
  const Rig detected = load_calibration(dir / "camchain.yaml");
  EXPECT_TRUE(detected.cameras[0].T_RS.isApprox(kalibr.cameras[0].T_RS, 0.0));
}

TEST(Calibration, LoadsKalibrEquidistantAndImu) {
  TempDir dir;
  write_text(dir / "camchain.yaml", R"(cam0:
  T_cam_imu: [[1, 0, 0, 0.1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
  camera_model: pinhole
  distortion_coeffs: [0.01, -0.02, 0.003, -0.0004]
  distortion_model: equidistant
  intrinsics: [190.97, 190.97, 254.93, 256.89]
  resolution: [512, 512]
cam1:
  T_cam_imu: [[1, 0, 0, -0.0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
  T_cn_cnm1: [[1, 0, 0, -0.1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
  camera_model: pinhole
  distortion_coeffs: []
  distortion_model: none
  intrinsics: [190, 190, 250, 250]
  resolution: [512, 512]
)");
  write_text(dir / "imu.yaml", R"(imu0:
  T_i_b: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
  accelerometer_noise_density: 0.0028
  accelerometer_random_walk: 0.00086
  gyroscope_noise_density: 0.00016
  gyroscope_random_walk: 2.2e-05
  model: calibrated
  rostopic: /imu0
  update_rate: 200.0
)");
  const Rig rig = load_kalibr(dir / "camchain.yaml", dir / "imu.yaml");
  ASSERT_EQ(rig.cameras.size(), 2u);
  EXPECT_EQ(rig.cameras[0].distortion, DistortionModel::Equidistant);
  EXPECT_DOUBLE_EQ(rig.cameras[0].distortion_coeffs[3], -0.0004);
  EXPECT_DOUBLE_EQ(rig.cameras[0].T_RS.translation().x(), -0.1);  // inverted T_cam_imu
  EXPECT_EQ(rig.cameras[1].distortion, DistortionModel::None);
  ASSERT_TRUE(rig.imu.has_value());
  EXPECT_DOUBLE_EQ(rig.imu->rate_hz, 200.0);
  EXPECT_DOUBLE_EQ(rig.imu->accel_noise_density, 0.0028);
  EXPECT_DOUBLE_EQ(rig.imu->gyro_random_walk, 2.2e-05);
  // A flat Kalibr input imu.yaml, auto-detected.
  write_text(dir / "imu_flat.yaml",
             "accelerometer_noise_density: 0.01\naccelerometer_random_walk: 0.0002\ngyroscope_noise_density: 0.005\n"
             "gyroscope_random_walk: 4.0e-06\nrostopic: /imu0\nupdate_rate: 100.0\n");
  const Rig flat = load_calibration(dir / "imu_flat.yaml");
  ASSERT_TRUE(flat.imu.has_value());
  EXPECT_DOUBLE_EQ(flat.imu->rate_hz, 100.0);
}

TEST(Calibration, NonOrthonormalRotationIsAnErrorNamingTheKey) {
  TempDir dir;
  write_text(dir / "cam0/sensor.yaml", R"(%YAML:1.0
sensor_type: camera
T_BS:
  cols: 4
  rows: 4
  data: [1.0, 0.0, 0.0, 0.0,  0.0, 1.0, 0.1, 0.0,  0.0, 0.0, 1.0, 0.0,  0.0, 0.0, 0.0, 1.0]
rate_hz: 20
resolution: [752, 480]
camera_model: pinhole
intrinsics: [458.654, 457.296, 367.215, 248.375]
distortion_model: radial-tangential
distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
)");
  EXPECT_THROW_WITH(load_euroc_camera(dir / "cam0/sensor.yaml"), ConfigError, "'T_BS' rotation is not orthonormal");
  write_text(dir / "chain.yaml",
             "cam0:\n  T_cam_imu: [[1,0,0,0],[0,-1,0,0],[0,0,1,0],[0,0,0,1]]\n  distortion_model: none\n"
             "  intrinsics: [1, 1, 0, 0]\n  resolution: [10, 10]\n");
  EXPECT_THROW_WITH(load_kalibr(dir / "chain.yaml"), ConfigError, "'T_cam_imu' rotation is not orthonormal");
}

TEST(Calibration, FarCameraIsAWarningNotAnError) {
  TempDir dir;
  write_text(dir / "chain.yaml",
             "cam0:\n  T_cam_imu: [[1,0,0,65.2],[0,1,0,0],[0,0,1,0],[0,0,0,1]]\n  distortion_model: none\n"
             "  intrinsics: [100, 100, 5, 5]\n  resolution: [10, 10]\n");
  const Rig rig = load_kalibr(dir / "chain.yaml");
  ASSERT_EQ(rig.warnings.size(), 1u);
  EXPECT_NE(rig.warnings[0].find("65.200 m"), std::string::npos) << rig.warnings[0];
  EXPECT_NE(rig.warnings[0].find("T_cam_imu"), std::string::npos);
}

TEST(Calibration, BadFilesGiveOneLineErrorsNamingFileAndProblem) {
  TempDir dir;
  write_text(dir / "bad.yaml", "cam0:\n  intrinsics: [1, 2\n  resolution: [3, 4]\n");
  EXPECT_THROW_WITH(load_calibration(dir / "bad.yaml"), ConfigError, "bad.yaml: malformed YAML at line");
  write_text(dir / "model.yaml",
             "cam0:\n  distortion_model: fov\n  distortion_coeffs: [0.9]\n  intrinsics: [1, 1, 0, 0]\n"
             "  resolution: [10, 10]\n");
  EXPECT_THROW_WITH(load_calibration(dir / "model.yaml"), ConfigError, "unknown distortion model 'fov'");
  write_text(dir / "count.yaml",
             "cam0:\n  distortion_model: radtan\n  distortion_coeffs: [0.1, 0.2]\n  intrinsics: [1, 1, 0, 0]\n"
             "  resolution: [10, 10]\n");
  EXPECT_THROW_WITH(load_calibration(dir / "count.yaml"), ConfigError, "takes 4 coefficients, got 2");
  write_text(dir / "fx.yaml", "cameras:\n  - width: 10\n    height: 10\n    intrinsics: [-1, 1, 0, 0]\n");
  EXPECT_THROW_WITH(load_calibration(dir / "fx.yaml"), ConfigError, "fx = -1 must be > 0");
  write_text(dir / "unknown.yaml", "cameras:\n  - width: 10\n    height: 10\n    intrinsics: [1, 1, 0, 0]\n    fu: 3\n");
  EXPECT_THROW_WITH(load_calibration(dir / "unknown.yaml"), ConfigError, "unknown key 'fu'");
  write_text(dir / "what.yaml", "foo: 1\n");
  EXPECT_THROW_WITH(load_calibration(dir / "what.yaml"), ConfigError, "not a known calibration file");
  EXPECT_THROW_WITH(load_calibration(dir / "nothing.yaml"), IoError, "nothing.yaml: file not found");
  write_text(dir / "cam.json", "{\"width\": 320, ");
  EXPECT_THROW_WITH(load_calibration(dir / "cam.json"), ConfigError, "cam.json: malformed JSON");
}

TEST(Calibration, LoadsMonoSlamCameraJson) {
  const std::string path = test::monoslam_dir() + "/camera.json";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "dataset monoslam-davison not found";
  const Rig rig = load_calibration(path);
  ASSERT_EQ(rig.cameras.size(), 1u);
  const auto& cam = rig.cameras[0];
  EXPECT_EQ(cam.width, 320);
  EXPECT_EQ(cam.height, 240);
  EXPECT_DOUBLE_EQ(cam.fx, 195.0);
  EXPECT_DOUBLE_EQ(cam.fy, 195.0);
  EXPECT_DOUBLE_EQ(cam.cx, 162.0);
  EXPECT_DOUBLE_EQ(cam.cy, 125.0);
  EXPECT_DOUBLE_EQ(cam.rate_hz, 25.0);  // what the file says (the sequence was recorded at 30)
  EXPECT_EQ(cam.distortion, DistortionModel::MonoSlamOneParam);
  ASSERT_EQ(cam.distortion_coeffs.size(), 1u);
  EXPECT_DOUBLE_EQ(cam.distortion_coeffs[0], 9e-6);
  // SceneLib camera frame (x left, y up) -> ours (x right, y down): a point right of centre in our camera frame
  // is on SceneLib's negative x.
  const Eigen::Vector3d p_R = cam.T_RS * Eigen::Vector3d(1.0, 2.0, 3.0);
  EXPECT_TRUE(p_R.isApprox(Eigen::Vector3d(-1.0, -2.0, 3.0)));
}

TEST(Calibration, RigYamlRoundTripIsExact) {
  TempDir dir;
  Rig rig;
  CameraCalibration cam;
  cam.name = "left";
  cam.width = 752;
  cam.height = 480;
  cam.rate_hz = 20;
  cam.fx = 458.654;
  cam.fy = 457.296;
  cam.cx = 367.215;
  cam.cy = 248.375;
  cam.distortion = DistortionModel::Equidistant;
  cam.distortion_coeffs = {0.1, -0.01, 1e-3, 1.0 / 3.0};
  cam.T_RS = Eigen::Translation3d(0.1, -0.2, 0.3) * Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized());
  rig.cameras.push_back(cam);
  ImuCalibration imu;
  imu.rate_hz = 200;
  imu.gyro_noise_density = 1.6968e-04;
  imu.gyro_random_walk = 1.9393e-05;
  imu.accel_noise_density = 2e-3;
  imu.accel_random_walk = 3e-3;
  imu.accel_saturation = 16 * 9.81;
  rig.imu = imu;
  rig.t_d = -1234567;
  write_rig_yaml(dir / "rig.yaml", rig);
  const Rig back = load_calibration(dir / "rig.yaml");
  ASSERT_EQ(back.cameras.size(), 1u);
  const auto& c = back.cameras[0];
  EXPECT_EQ(c.name, "left");
  EXPECT_EQ(c.fx, cam.fx);
  EXPECT_EQ(c.distortion, cam.distortion);
  EXPECT_EQ(c.distortion_coeffs, cam.distortion_coeffs);
  EXPECT_EQ(c.T_RS.matrix(), cam.T_RS.matrix());
  ASSERT_TRUE(back.imu.has_value());
  EXPECT_EQ(back.imu->gyro_noise_density, imu.gyro_noise_density);
  EXPECT_EQ(back.imu->accel_saturation, imu.accel_saturation);
  EXPECT_FALSE(back.imu->gyro_saturation.has_value());
  EXPECT_EQ(back.t_d, rig.t_d);
  // Review 27 Nov: t_d_ns had no bound (t_d in seconds had one), and 9e18 ns overflowed each image's time.
  std::string text = read_text(dir / "rig.yaml");
  text.replace(text.find("t_d_ns: -1234567"), 16, "t_d_ns: 9210000000000000000");  // an int64, beyond the bound
  write_text(dir / "rig.yaml", text);
  EXPECT_THROW_WITH(load_calibration(dir / "rig.yaml"), ConfigError, "t_d_ns = 9.21e+18 must be within +-9.2e18 ns");
}

TEST(Calibration, EurocDistortionCoefficientsWithoutAModelAreAnError) {
  // Review 27 Nov: they were dropped silently (a pinhole camera assumed).
  TempDir dir;
  write_text(dir / "sensor.yaml",
             "sensor_type: camera\nrate_hz: 20\nresolution: [752, 480]\ncamera_model: pinhole\n"
             "intrinsics: [458.654, 457.296, 367.215, 248.375]\n"
             "distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]\n"
             "T_BS:\n  cols: 4\n  rows: 4\n  data: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n");
  EXPECT_THROW_WITH(load_euroc_camera(dir / "sensor.yaml"), ConfigError,
                    "distortion_coefficients without distortion_model");
}

TEST(Calibration, KalibrCamerasOnlyChainsEachCameraToThePreviousOne) {
  // kalibr_calibrate_cameras writes no T_cam_imu: cam0 is the reference and T_cn_cnm1 (camera n from camera n-1)
  // places the others. cam1 used to stay at cam0's pose: a stereo rig with a zero baseline, and no message.
  TempDir dir;
  const std::string intrinsics = R"(  camera_model: pinhole
  distortion_coeffs: [-0.28, 0.07, 0.0002, 0.00002]
  distortion_model: radtan
  intrinsics: [458.6, 457.3, 367.2, 248.4]
  resolution: [752, 480]
)";
  const std::string cam1 =
      "cam1:\n  T_cn_cnm1: [[0.999997, 0.002312, 0.000376, -0.110074],\n"
      "    [-0.002315, 0.999898, 0.014089, 0.000399],\n"
      "    [-0.000344, -0.014090, 0.999901, -0.000853], [0, 0, 0, 1]]\n";
  const std::string cam2 = "cam2:\n  T_cn_cnm1: [[1, 0, 0, -0.05], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n";
  write_text(dir / "camchain.yaml", "cam0:\n" + intrinsics + cam1 + intrinsics + cam2 + intrinsics);
  const Rig rig = load_kalibr(dir / "camchain.yaml");
  ASSERT_EQ(rig.cameras.size(), 3u);
  EXPECT_TRUE(rig.cameras[0].T_RS.matrix().isIdentity(0.0));
  // cam1 in cam0: the inverse of T_c1_c0, about 11 cm along +x (EuRoC's baseline).
  const Eigen::Vector3d p1 = rig.cameras[1].T_RS.translation();
  EXPECT_NEAR(p1.x(), 0.110, 1e-3) << p1.transpose();
  EXPECT_NEAR(p1.norm(), 0.110, 1e-3);
  // T_RS(1) maps cam1's points to cam0's, so T_c1_c0 T_RS(1) is the identity.
  Eigen::Matrix4d T10;
  T10 << 0.999997, 0.002312, 0.000376, -0.110074, -0.002315, 0.999898, 0.014089, 0.000399, -0.000344, -0.014090,
      0.999901, -0.000853, 0, 0, 0, 1;
  EXPECT_LT((T10 * rig.cameras[1].T_RS.matrix() - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff(), 1e-5);
  // cam2 follows cam1: 5 cm further along cam1's x.
  const Eigen::Vector3d p2 = rig.cameras[2].T_RS.translation();
  EXPECT_LT((p2 - (rig.cameras[1].T_RS * Eigen::Vector3d(0.05, 0, 0))).norm(), 1e-12);
  EXPECT_FALSE(rig.r_is_imu);
  // Its cameras are not placed relative to any IMU: an IMU file (a valid one) cannot be paired with it.
  write_text(dir / "imu.yaml",
             "accelerometer_noise_density: 0.01\naccelerometer_random_walk: 0.0002\ngyroscope_noise_density: 0.005\n"
             "gyroscope_random_walk: 4.0e-06\nrostopic: /imu0\nupdate_rate: 100.0\n");
  ASSERT_TRUE(load_calibration(dir / "imu.yaml").imu.has_value());
  EXPECT_THROW_WITH(load_kalibr(dir / "camchain.yaml", dir / "imu.yaml"), ConfigError,
                    "a cameras-only calibration (no 'T_cam_imu') with the IMU file");
  // A camera after cam0 with neither key, or T_cam_imu on some cameras only: errors naming the camera.
  write_text(dir / "orphan.yaml", "cam0:\n" + intrinsics + "cam1:\n" + intrinsics);
  EXPECT_THROW_WITH(load_kalibr(dir / "orphan.yaml"), ConfigError,
                    "cam1: neither 'T_cam_imu' nor 'T_cn_cnm1': its pose relative to cam0 is unknown");
  write_text(dir / "mixed.yaml", "cam0:\n" + intrinsics +
                                     "cam1:\n  T_cam_imu: [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n" +
                                     intrinsics);
  EXPECT_THROW_WITH(load_kalibr(dir / "mixed.yaml"), ConfigError, "cam1: 'T_cam_imu' while cam0 has none");
}

TEST(Calibration, ARigYamlImuOffTheRobotFrameMovesTheFrameOntoIt) {
  // The inertial robot's frame is its IMU: a rig whose IMU is 10 cm along R's x and turned 90° about z gets its
  // cameras re-expressed in the IMU's frame (the IMU's extrinsic was read and then ignored).
  TempDir dir;
  Rig rig;
  CameraCalibration cam;
  cam.name = "cam0";
  cam.width = 752;
  cam.height = 480;
  cam.fx = cam.fy = 458;
  cam.cx = 367;
  cam.cy = 248;
  cam.T_RS = Eigen::Translation3d(0.0, 0.2, 0.0) * Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX());
  rig.cameras.push_back(cam);
  ImuCalibration imu = test::small_imu();
  const Eigen::Isometry3d T_RI(Eigen::Translation3d(0.1, 0.0, 0.0) *
                               Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  imu.T_RS = T_RI;
  rig.imu = imu;
  write_rig_yaml(dir / "rig.yaml", rig);
  const Rig back = load_calibration(dir / "rig.yaml");
  ASSERT_TRUE(back.imu.has_value());
  EXPECT_TRUE(back.imu->T_RS.matrix().isIdentity(0.0));
  EXPECT_TRUE(back.cameras[0].T_RS.isApprox(T_RI.inverse() * cam.T_RS, 1e-12));
  // The camera's centre, (0, 0.2, 0) in R, seen from the IMU at (0.1, 0, 0) turned 90°: (0.2, 0.1, 0).
  EXPECT_TRUE(back.cameras[0].T_RS.translation().isApprox(Eigen::Vector3d(0.2, 0.1, 0.0), 1e-12))
      << back.cameras[0].T_RS.translation().transpose();
}

TEST(Calibration, ARotationWrittenWithFiveDecimalsIsMadeOrthonormalWithAWarning) {
  // EuRoC's cam0 T_BS rounded to 5 decimals: max |RᵀR − I| about 1e-5, refused before (the bound was 1e-6).
  TempDir dir;
  write_text(dir / "sensor.yaml", R"(%YAML:1.0
sensor_type: camera
T_BS:
  cols: 4
  rows: 4
  data: [0.01487, -0.99988, 0.00414, -0.02164,  0.99956, 0.01497, 0.02572, -0.06468,
         -0.02577, 0.00376, 0.99966, 0.00981,  0.0, 0.0, 0.0, 1.0]
rate_hz: 20
resolution: [752, 480]
camera_model: pinhole
intrinsics: [458.654, 457.296, 367.215, 248.375]
distortion_model: radial-tangential
distortion_coefficients: [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05]
)");
  std::vector<std::string> warnings;
  const CameraCalibration cam = load_euroc_camera(dir / "sensor.yaml", &warnings);
  const Eigen::Matrix3d R = cam.T_RS.linear();
  EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(R(0, 1), -0.99988, 1e-4);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("'T_BS' rotation is orthonormal only to"), std::string::npos) << warnings[0];
}

TEST(Calibration, KittiCameraCentreIsMinusKInverseTimesTheLastColumn) {
  // KITTI odometry 00's P2: P = K [I | t] with t_z = 2.745884e-03, so t_x is (P03 − cx t_z) / fx, not P03 / fx
  // (about 2.3 mm apart).
  TempDir dir;
  write_text(dir / "calib.txt",
             "P0: 7.188560e+02 0.000000e+00 6.071928e+02 0.000000e+00 0.000000e+00 7.188560e+02 1.852157e+02 "
             "0.000000e+00 0.000000e+00 0.000000e+00 1.000000e+00 0.000000e+00\n"
             "P2: 7.188560e+02 0.000000e+00 6.071928e+02 4.538225e+01 0.000000e+00 7.188560e+02 1.852157e+02 "
             "-1.130887e-01 0.000000e+00 0.000000e+00 1.000000e+00 3.779761e-03\n");
  const CameraCalibration cam = load_kitti_calib(dir / "calib.txt", 2);
  const double tz = 3.779761e-03;
  const Eigen::Vector3d t((4.538225e+01 - 6.071928e+02 * tz) / 7.188560e+02,
                          (-1.130887e-01 - 1.852157e+02 * tz) / 7.188560e+02, tz);
  EXPECT_TRUE(cam.T_RS.translation().isApprox(-t, 1e-12)) << cam.T_RS.translation().transpose();
  EXPECT_GT(std::abs(cam.T_RS.translation().x() + 4.538225e+01 / 7.188560e+02), 2e-3);  // the old formula's error
}

}  // namespace
}  // namespace rtslam::io
