#include "rtslam/io/calibration.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <Eigen/SVD>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/source.hpp"
#include "rtslam/io/text.hpp"

namespace rtslam::io {
namespace fs = std::filesystem;
namespace {

/// A required scalar of a foreign (non-strict) YAML mapping.
template <class T>
T need(const YAML::Node& node, const std::string& key, const std::string& where) {
  if (!node[key]) throw ConfigError(fmt::format("{}: missing required key '{}'", where, key));
  try {
    return node[key].as<T>();
  } catch (const YAML::Exception& e) {
    throw ConfigError(fmt::format("{}: cannot read '{}' ({})", where, key, e.msg));
  }
}

/// A list of exactly n (or, if n < 0, any number of) doubles; a list of rows is flattened; an OpenCV
/// {rows, cols, data} mapping reads its data.
std::vector<double> numbers(const YAML::Node& node, const std::string& key, const std::string& where, int n) {
  if (!node[key]) throw ConfigError(fmt::format("{}: missing required key '{}'", where, key));
  const YAML::Node n0 = node[key];
  const YAML::Node data = n0.IsMap() && n0["data"] ? n0["data"] : n0;
  if (!data.IsSequence()) throw ConfigError(fmt::format("{}: '{}' must be a list of numbers", where, key));
  std::vector<double> out;
  try {
    for (const auto& item : data) {
      if (item.IsSequence()) {
        for (const auto& x : item) out.push_back(x.as<double>());
      } else {
        out.push_back(item.as<double>());
      }
    }
  } catch (const YAML::Exception& e) {
    throw ConfigError(fmt::format("{}: cannot read '{}' as numbers ({})", where, key, e.msg));
  }
  if (n >= 0 && static_cast<int>(out.size()) != n) {
    throw ConfigError(fmt::format("{}: '{}' has {} numbers, expected {}", where, key, out.size(), n));
  }
  for (double x : out) {
    if (!std::isfinite(x)) throw ConfigError(fmt::format("{}: '{}' contains a non-finite number", where, key));
  }
  return out;
}

/// An image side [px] given as a number in a foreign file: an integer in [1, kMaxImageSide] (a cast of anything else
/// to int would be undefined or silently truncated).
int image_side(double v, const std::string& where, const std::string& key) {
  require_bound(v >= 1 && v <= kMaxImageSide && v == std::floor(v), where, key, v,
                fmt::format("an integer in [1, {}]", kMaxImageSide));
  return static_cast<int>(v);
}

/// A time offset in seconds, converted to ns: it must be finite and within the int64 ns range.
TimeNs offset_ns(double seconds, const std::string& where, const std::string& key) {
  require_bound(std::isfinite(seconds) && std::abs(seconds) <= 9.2e9, where, key, seconds,
                "finite and within +-9.2e9 s");
  return from_seconds(seconds);
}

/// Runs a loader; a yaml-cpp exception that escapes it (a node of another kind than the loader expects, met
/// somewhere not checked explicitly) becomes a ConfigError naming the file.
template <class F>
auto translate_yaml_errors(const std::string& path, F&& load) -> decltype(load()) {
  try {
    return load();
  } catch (const YAML::Exception& e) {
    throw ConfigError(e.mark.is_null() ? fmt::format("{}: {}", path, e.msg)
                                       : fmt::format("{}: line {}: {}", path, e.mark.line + 1, e.msg));
  }
}

Eigen::Matrix4d matrix4(const YAML::Node& node, const std::string& key, const std::string& where) {
  const auto v = numbers(node, key, where, 16);
  Eigen::Matrix4d T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = v[static_cast<size_t>(4 * r + c)];
  return T;
}

// Max |RᵀR − I| of a calibration's rotation: below kOrthonormal taken as it is (the published files: ~1e-8), up to
// kRoughlyOrthonormal (a matrix written with 4–5 decimals) replaced by the nearest rotation, beyond refused.
constexpr double kOrthonormal = 1e-6, kRoughlyOrthonormal = 1e-3;

double orthonormality_error(const Eigen::Matrix3d& R) {
  return (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
}

Eigen::Isometry3d to_isometry(const Eigen::Matrix4d& T) {
  Eigen::Isometry3d iso = Eigen::Isometry3d::Identity();
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  if (orthonormality_error(R) < kOrthonormal) {
    iso.linear() = R;
  } else {  // the nearest rotation (polar decomposition); check_extrinsic bounded the error and the sign
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
    iso.linear() = svd.matrixU() * svd.matrixV().transpose();
  }
  iso.translation() = T.topRightCorner<3, 1>();
  return iso;
}

}  // namespace

void check_camera_calibration(const CameraCalibration& cam, const std::string& where) {
  require_bound(cam.width > 0 && cam.width <= kMaxImageSide, where, "width", cam.width,
                fmt::format("in [1, {}]", kMaxImageSide));
  require_bound(cam.height > 0 && cam.height <= kMaxImageSide, where, "height", cam.height,
                fmt::format("in [1, {}]", kMaxImageSide));
  const long long pixels = static_cast<long long>(cam.width) * cam.height;
  require_bound(pixels <= kMaxImagePixels, where, "width x height", static_cast<double>(pixels),
                fmt::format("<= {}", kMaxImagePixels));
  require_bound(cam.fx > 0 && std::isfinite(cam.fx), where, "fx", cam.fx, "> 0");
  require_bound(cam.fy > 0 && std::isfinite(cam.fy), where, "fy", cam.fy, "> 0");
  require_bound(std::isfinite(cam.cx), where, "cx", cam.cx, "finite");
  require_bound(std::isfinite(cam.cy), where, "cy", cam.cy, "finite");
  // Plausibility: a focal length gives the field of view 2 atan(side / 2f) across the image; a lens outside
  // [kMinFovDeg, kMaxFovDeg] is a wrong number (a unit slip, a swapped key), not a camera. Fisheye calibrations
  // (equidistant) have pinhole-like focal lengths too (Kalibr's EuRoC fisheye: 190 px on 752 px, 126 deg).
  const auto focal_bounds = [](int side) {
    constexpr double kDeg = M_PI / 180.0;
    return std::pair{side / (2.0 * std::tan(0.5 * CameraCalibration::kMaxFovDeg * kDeg)),
                     side / (2.0 * std::tan(0.5 * CameraCalibration::kMinFovDeg * kDeg))};
  };
  const auto [fx_min, fx_max] = focal_bounds(cam.width);
  const auto [fy_min, fy_max] = focal_bounds(cam.height);
  const std::string fov = fmt::format("a field of view in [{:g}, {:g}] deg", CameraCalibration::kMinFovDeg,
                                      CameraCalibration::kMaxFovDeg);
  require_bound(cam.fx >= fx_min && cam.fx <= fx_max, where, "fx", cam.fx,
                fmt::format("in [{:.4g}, {:.4g}] px for {} over the {} px width", fx_min, fx_max, fov, cam.width));
  require_bound(cam.fy >= fy_min && cam.fy <= fy_max, where, "fy", cam.fy,
                fmt::format("in [{:.4g}, {:.4g}] px for {} over the {} px height", fy_min, fy_max, fov, cam.height));
  require_bound(cam.fx / cam.fy >= 0.25 && cam.fx / cam.fy <= 4.0, where, "fx / fy", cam.fx / cam.fy,
                "in [0.25, 4] (pixel aspect ratio)");
  require_bound(cam.cx >= 0.0 && cam.cx <= cam.width, where, "cx", cam.cx,
                fmt::format("inside the image, in [0, {}] px", cam.width));
  require_bound(cam.cy >= 0.0 && cam.cy <= cam.height, where, "cy", cam.cy,
                fmt::format("inside the image, in [0, {}] px", cam.height));
  require_bound(cam.rate_hz == 0.0 || (cam.rate_hz >= 1e-3 && cam.rate_hz <= 1e5), where, "rate_hz", cam.rate_hz,
                "0 (unknown) or in [1e-3, 1e5] Hz");
  const int n = distortion_coefficient_count(cam.distortion);
  if (static_cast<int>(cam.distortion_coeffs.size()) != n) {
    throw ConfigError(fmt::format("{}: distortion model '{}' takes {} coefficients, got {}", where,
                                  to_string(cam.distortion), n, cam.distortion_coeffs.size()));
  }
  for (double k : cam.distortion_coeffs) {
    if (!std::isfinite(k)) throw ConfigError(fmt::format("{}: a distortion coefficient is not finite", where));
    require_bound(std::abs(k) <= 1e3, where, "distortion coefficient", k, "in [-1e3, 1e3]");
  }
}

namespace {

void check_intrinsics(const CameraCalibration& cam, const std::string& where) { check_camera_calibration(cam, where); }

void check_imu(const ImuCalibration& imu, const std::string& where) {
  const auto positive = [](double x) { return x > 0 && std::isfinite(x); };
  const auto non_negative = [](double x) { return x >= 0 && std::isfinite(x); };
  require_bound(positive(imu.rate_hz), where, "rate_hz", imu.rate_hz, "> 0, finite");
  require_bound(imu.rate_hz <= 1e5, where, "rate_hz", imu.rate_hz, "<= 1e5 Hz");
  // Noise densities: the filter's own keys allow (0, 10); a calibration beyond is a unit slip.
  require_bound(positive(imu.gyro_noise_density), where, "gyroscope_noise_density", imu.gyro_noise_density,
                "> 0, finite");
  require_bound(imu.gyro_noise_density < 10.0, where, "gyroscope_noise_density", imu.gyro_noise_density, "< 10");
  require_bound(positive(imu.accel_noise_density), where, "accelerometer_noise_density", imu.accel_noise_density,
                "> 0, finite");
  require_bound(imu.accel_noise_density < 10.0, where, "accelerometer_noise_density", imu.accel_noise_density,
                "< 10");
  require_bound(non_negative(imu.gyro_random_walk), where, "gyroscope_random_walk", imu.gyro_random_walk,
                ">= 0, finite");
  require_bound(imu.gyro_random_walk < 10.0, where, "gyroscope_random_walk", imu.gyro_random_walk, "< 10");
  require_bound(non_negative(imu.accel_random_walk), where, "accelerometer_random_walk", imu.accel_random_walk,
                ">= 0, finite");
  require_bound(imu.accel_random_walk < 10.0, where, "accelerometer_random_walk", imu.accel_random_walk, "< 10");
  if (imu.gyro_saturation) {
    require_bound(positive(*imu.gyro_saturation), where, "gyroscope_saturation", *imu.gyro_saturation,
                  "> 0, finite");
    require_bound(*imu.gyro_saturation <= ImuRange::kMaxPlausibleGyro, where, "gyroscope_saturation",
                  *imu.gyro_saturation, fmt::format("<= {:g} rad/s", ImuRange::kMaxPlausibleGyro));
  }
  if (imu.accel_saturation) {
    require_bound(positive(*imu.accel_saturation), where, "accelerometer_saturation", *imu.accel_saturation,
                  "> 0, finite");
    require_bound(*imu.accel_saturation <= ImuRange::kMaxPlausibleAccel, where, "accelerometer_saturation",
                  *imu.accel_saturation, fmt::format("<= {:g} m/s²", ImuRange::kMaxPlausibleAccel));
  }
}

std::string folder_name(const std::string& path) {
  const fs::path parent = fs::path(path).parent_path();
  return parent.empty() ? std::string("cam0") : parent.filename().string();
}

}  // namespace

std::string to_string(DistortionModel model) {
  switch (model) {
    case DistortionModel::None:
      return "none";
    case DistortionModel::RadTan:
      return "radtan";
    case DistortionModel::Equidistant:
      return "equidistant";
    case DistortionModel::MonoSlamOneParam:
      return "monoslam_one_param";
  }
  return "unknown";
}

DistortionModel distortion_model_from_string(const std::string& name, const std::string& where) {
  const std::string n = to_lower(name);
  if (n == "none" || n == "pinhole") return DistortionModel::None;
  if (n == "radtan" || n == "radial-tangential" || n == "radial_tangential" || n == "plumb_bob")
    return DistortionModel::RadTan;
  if (n == "equidistant" || n == "equi" || n == "fisheye" || n == "kannala_brandt") return DistortionModel::Equidistant;
  if (n == "monoslam_one_param" || n == "monoslam" || n == "wideangle") return DistortionModel::MonoSlamOneParam;
  throw ConfigError(fmt::format("{}: unknown distortion model '{}' (known: none, radtan, equidistant, "
                                "monoslam_one_param)",
                                where, name));
}

int distortion_coefficient_count(DistortionModel model) {
  switch (model) {
    case DistortionModel::None:
      return 0;
    case DistortionModel::RadTan:
    case DistortionModel::Equidistant:
      return 4;
    case DistortionModel::MonoSlamOneParam:
      return 1;
  }
  return 0;
}

void check_extrinsic(const Eigen::Matrix4d& T, const std::string& where, const std::string& key,
                     std::vector<std::string>* warnings, bool warn_far) {
  if (!T.allFinite()) throw ConfigError(fmt::format("{}: '{}' contains a non-finite number", where, key));
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const double err = orthonormality_error(R);
  const double det = R.determinant();
  if (!(err < kRoughlyOrthonormal) || !(det > 0.0)) {
    throw ConfigError(fmt::format("{}: '{}' rotation is not orthonormal (max |R^T R - I| = {:.3g}, det = {:.6g})",
                                  where, key, err, det));
  }
  if (err >= kOrthonormal && warnings != nullptr) {
    warnings->push_back(fmt::format("{}: '{}' rotation is orthonormal only to {:.2g} (written with few decimals?): "
                                    "the nearest rotation is used",
                                    where, key, err));
  }
  const Eigen::RowVector4d last = T.row(3);
  if ((last - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
    throw ConfigError(fmt::format("{}: '{}' last row must be [0 0 0 1]", where, key));
  }
  const double d = T.topRightCorner<3, 1>().norm();
  if (warn_far && d > 0.5) {
    const std::string msg = fmt::format(
        "{}: '{}' puts the sensor {:.3f} m from the robot frame (> 0.5 m): is the transform inverted or in the wrong "
        "unit?",
        where, key, d);
    logger("io")->warn("{}", msg);
    if (warnings) warnings->push_back(msg);
  }
}

YAML::Node load_yaml_lenient(const std::string& path) {
  if (!fs::is_regular_file(path)) throw IoError(fmt::format("{}: file not found", path));
  std::ifstream in(path);
  if (!in) throw IoError(fmt::format("{}: cannot open for reading", path));
  std::stringstream ss;
  ss << in.rdbuf();
  std::string text = ss.str();
  // OpenCV FileStorage writes "%YAML:1.0" (not a valid YAML directive): comment it out, keeping line numbers.
  if (text.rfind("%YAML:", 0) == 0 || text.rfind("%YAML 1.0", 0) == 0) text.insert(0, "#");
  YAML::Node node;
  try {
    node = YAML::Load(text);
  } catch (const YAML::ParserException& e) {
    throw ConfigError(fmt::format("{}: malformed YAML at line {}: {}", path, e.mark.line + 1, e.msg));
  } catch (const YAML::Exception& e) {
    throw IoError(fmt::format("{}: cannot read YAML: {}", path, e.msg));
  }
  check_unique_keys(node, path);
  return node;
}

namespace {

CameraCalibration euroc_camera(const std::string& path, std::vector<std::string>* warnings) {
  const YAML::Node y = load_yaml_lenient(path);
  if (!y.IsMap()) throw ConfigError(fmt::format("{}: expected a mapping", path));
  if (y["sensor_type"] && to_lower(need<std::string>(y, "sensor_type", path)) != "camera") {
    throw ConfigError(fmt::format("{}: sensor_type is '{}', expected 'camera'", path,
                                  need<std::string>(y, "sensor_type", path)));
  }
  CameraCalibration cam;
  cam.name = folder_name(path);
  const std::string model = y["camera_model"] ? need<std::string>(y, "camera_model", path) : "pinhole";
  if (to_lower(model) != "pinhole") {
    throw ConfigError(fmt::format("{}: camera_model '{}' is not supported (only pinhole)", path, model));
  }
  const auto res = numbers(y, "resolution", path, 2);
  cam.width = image_side(res[0], path, "resolution[0]");
  cam.height = image_side(res[1], path, "resolution[1]");
  if (y["rate_hz"]) cam.rate_hz = need<double>(y, "rate_hz", path);
  const auto k = numbers(y, "intrinsics", path, 4);
  cam.fx = k[0];
  cam.fy = k[1];
  cam.cx = k[2];
  cam.cy = k[3];
  if (!y["distortion_model"] && y["distortion_coefficients"]) {
    throw ConfigError(fmt::format("{}: distortion_coefficients without distortion_model: say which model they are "
                                  "for (radial-tangential, equidistant, ...; 'none' to ignore them)", path));
  }
  cam.distortion = distortion_model_from_string(
      y["distortion_model"] ? need<std::string>(y, "distortion_model", path) : "none", path + ": distortion_model");
  if (cam.distortion != DistortionModel::None) cam.distortion_coeffs = numbers(y, "distortion_coefficients", path, -1);
  check_intrinsics(cam, path);
  const Eigen::Matrix4d T_BS = matrix4(y, "T_BS", path);
  check_extrinsic(T_BS, path, "T_BS", warnings);
  cam.T_RS = to_isometry(T_BS);
  return cam;
}

}  // namespace

CameraCalibration load_euroc_camera(const std::string& path, std::vector<std::string>* warnings) {
  return translate_yaml_errors(path, [&] { return euroc_camera(path, warnings); });
}

namespace {

ImuCalibration euroc_imu(const std::string& path) {
  const YAML::Node y = load_yaml_lenient(path);
  if (!y.IsMap()) throw ConfigError(fmt::format("{}: expected a mapping", path));
  if (y["sensor_type"] && to_lower(need<std::string>(y, "sensor_type", path)) != "imu") {
    throw ConfigError(fmt::format("{}: sensor_type is '{}', expected 'imu'", path,
                                  need<std::string>(y, "sensor_type", path)));
  }
  ImuCalibration imu;
  imu.name = folder_name(path);
  imu.rate_hz = need<double>(y, "rate_hz", path);
  imu.gyro_noise_density = need<double>(y, "gyroscope_noise_density", path);
  imu.gyro_random_walk = need<double>(y, "gyroscope_random_walk", path);
  imu.accel_noise_density = need<double>(y, "accelerometer_noise_density", path);
  imu.accel_random_walk = need<double>(y, "accelerometer_random_walk", path);
  if (y["gyroscope_saturation"]) imu.gyro_saturation = need<double>(y, "gyroscope_saturation", path);
  if (y["accelerometer_saturation"]) imu.accel_saturation = need<double>(y, "accelerometer_saturation", path);
  check_imu(imu, path);
  const Eigen::Matrix4d T_BS = matrix4(y, "T_BS", path);
  check_extrinsic(T_BS, path, "T_BS", nullptr, false);
  imu.T_RS = to_isometry(T_BS);
  return imu;
}

}  // namespace

ImuCalibration load_euroc_imu(const std::string& path) {
  return translate_yaml_errors(path, [&] { return euroc_imu(path); });
}

namespace {

ImuCalibration kalibr_imu(const std::string& path) {
  const YAML::Node root = load_yaml_lenient(path);
  if (!root.IsMap()) throw ConfigError(fmt::format("{}: expected a mapping", path));
  const YAML::Node y = root["imu0"] ? root["imu0"] : root;
  const std::string where = root["imu0"] ? path + "/imu0" : path;
  if (!y.IsMap()) throw ConfigError(fmt::format("{}: expected a mapping", where));
  ImuCalibration imu;
  imu.rate_hz = need<double>(y, "update_rate", where);
  imu.gyro_noise_density = need<double>(y, "gyroscope_noise_density", where);
  imu.gyro_random_walk = need<double>(y, "gyroscope_random_walk", where);
  imu.accel_noise_density = need<double>(y, "accelerometer_noise_density", where);
  imu.accel_random_walk = need<double>(y, "accelerometer_random_walk", where);
  check_imu(imu, where);
  // The IMU is the robot frame R: T_RS of the IMU is the identity whatever T_i_b says about a separate body frame.
  if (y["T_i_b"]) check_extrinsic(matrix4(y, "T_i_b", where), where, "T_i_b", nullptr, false);
  return imu;
}

}  // namespace

ImuCalibration load_kalibr_imu(const std::string& path) {
  return translate_yaml_errors(path, [&] { return kalibr_imu(path); });
}

namespace {

Rig kalibr(const std::string& camchain_path, const std::string& imu_path) {
  const YAML::Node root = load_yaml_lenient(camchain_path);
  if (!root.IsMap()) throw ConfigError(fmt::format("{}: expected a mapping", camchain_path));
  Rig rig;
  bool first = true;
  bool with_imu = false;  // cam0 has T_cam_imu
  for (int i = 0;; ++i) {
    const std::string name = fmt::format("cam{}", i);
    if (!root[name]) break;
    const YAML::Node y = root[name];
    const std::string where = camchain_path + "/" + name;
    if (!y.IsMap()) throw ConfigError(fmt::format("{}: expected a mapping", where));
    CameraCalibration cam;
    cam.name = name;
    const std::string model = y["camera_model"] ? need<std::string>(y, "camera_model", where) : "pinhole";
    if (to_lower(model) != "pinhole") {
      throw ConfigError(fmt::format("{}: camera_model '{}' is not supported (only pinhole)", where, model));
    }
    const auto res = numbers(y, "resolution", where, 2);
    cam.width = image_side(res[0], where, "resolution[0]");
    cam.height = image_side(res[1], where, "resolution[1]");
    const auto k = numbers(y, "intrinsics", where, 4);
    cam.fx = k[0];
    cam.fy = k[1];
    cam.cx = k[2];
    cam.cy = k[3];
    cam.distortion = distortion_model_from_string(need<std::string>(y, "distortion_model", where),
                                                  where + ": distortion_model");
    if (cam.distortion != DistortionModel::None) cam.distortion_coeffs = numbers(y, "distortion_coeffs", where, -1);
    if (y["rate_hz"]) cam.rate_hz = need<double>(y, "rate_hz", where);
    check_intrinsics(cam, where);
    // T_cam_imu (camera from IMU: an IMU-camera calibration) puts the camera in R = the IMU. A cameras-only
    // calibration (kalibr_calibrate_cameras) has none: R is cam0, and camera n follows camera n-1 through
    // T_cn_cnm1 (camera n from camera n-1).
    if (y["T_cam_imu"]) {
      if (i > 0 && !with_imu) {
        throw ConfigError(fmt::format("{}: 'T_cam_imu' while cam0 has none (cam0 is then the reference): give it "
                                      "for every camera or for none",
                                      where));
      }
      const Eigen::Matrix4d T_SR = matrix4(y, "T_cam_imu", where);
      check_extrinsic(T_SR, where, "T_cam_imu", &rig.warnings);
      cam.T_RS = to_isometry(T_SR).inverse();
      with_imu = true;
    } else if (i > 0 && with_imu) {
      throw ConfigError(fmt::format("{}: no 'T_cam_imu' while cam0 has one: give it for every camera", where));
    } else if (i > 0) {
      if (!y["T_cn_cnm1"]) {
        throw ConfigError(fmt::format("{}: neither 'T_cam_imu' nor 'T_cn_cnm1': its pose relative to cam{} is "
                                      "unknown",
                                      where, i - 1));
      }
      const Eigen::Matrix4d T_n_prev = matrix4(y, "T_cn_cnm1", where);
      check_extrinsic(T_n_prev, where, "T_cn_cnm1", &rig.warnings);
      cam.T_RS = rig.cameras.back().T_RS * to_isometry(T_n_prev).inverse();
    }
    if (first && y["timeshift_cam_imu"]) {
      rig.t_d = offset_ns(need<double>(y, "timeshift_cam_imu", where), where, "timeshift_cam_imu");
    }
    first = false;
    rig.cameras.push_back(cam);
  }
  if (rig.cameras.empty()) throw ConfigError(fmt::format("{}: no 'cam0' entry: not a Kalibr camchain", camchain_path));
  rig.r_is_imu = with_imu;
  if (!imu_path.empty()) {
    if (!with_imu) {
      throw ConfigError(fmt::format("{}: a cameras-only calibration (no 'T_cam_imu') with the IMU file {}: the "
                                    "cameras' pose relative to the IMU is unknown",
                                    camchain_path, imu_path));
    }
    rig.imu = load_kalibr_imu(imu_path);
  }
  return rig;
}

}  // namespace

Rig load_kalibr(const std::string& camchain_path, const std::string& imu_path) {
  return translate_yaml_errors(camchain_path, [&] { return kalibr(camchain_path, imu_path); });
}

Rig load_euroc_folder_calibration(const std::string& mav0_in, const std::vector<int>& cameras, FolderImu imu) {
  fs::path mav0 = fs::path(mav0_in).lexically_normal();
  if (!mav0.has_filename()) mav0 = mav0.parent_path();  // "…/mav0/"
  const fs::path imu_yaml = mav0 / "imu0" / "sensor.yaml";
  const auto camera_yaml = [&](int c) { return mav0 / fmt::format("cam{}", c) / "sensor.yaml"; };
  // The Kalibr files' folder: beside mav0/, inside the folder given, or the folder given (a bag's --calibration).
  const fs::path dso = mav0.filename() == "dso"    ? mav0
                       : mav0.filename() == "mav0" ? mav0.parent_path() / "dso"
                                                   : mav0 / "dso";
  const bool euroc_cameras =
      std::any_of(cameras.begin(), cameras.end(), [&](int c) { return fs::is_regular_file(camera_yaml(c)); });
  if (!cameras.empty() && !euroc_cameras && fs::is_regular_file(dso / "camchain.yaml")) {
    // TUM-VI: the cameras relative to the IMU (T_cam_imu) and the IMU's noise in Kalibr's files.
    const std::string camchain = (dso / "camchain.yaml").string();
    const fs::path imu_config = dso / "imu_config.yaml";
    std::string imu_path;
    if (imu != FolderImu::Skip && fs::is_regular_file(imu_config)) {
      imu_path = imu_config.string();
    } else if (imu == FolderImu::Required) {
      throw IoError(fmt::format("{}: file not found: an inertial run needs the IMU's noise (the calibration of {} "
                                "is TUM-VI's {})",
                                imu_config.string(), mav0.string(), camchain));
    }
    const Rig all = load_kalibr(camchain, imu_path);
    logger("io")->info("{}: no sensor.yaml files; calibration from TUM-VI's {}{}", mav0.string(), camchain,
                       imu_path.empty() ? std::string() : " and " + imu_path);
    Rig rig = all;
    rig.cameras.clear();
    for (const int c : cameras) {
      if (c < 0 || static_cast<size_t>(c) >= all.cameras.size()) {
        throw ConfigError(fmt::format("{}: has no camera {} (it has {})", camchain, c, all.cameras.size()));
      }
      rig.cameras.push_back(all.cameras[static_cast<size_t>(c)]);
    }
    return rig;
  }
  for (const int c : cameras) {
    if (!fs::is_regular_file(camera_yaml(c))) {
      throw IoError(fmt::format("{}: file not found (camera {}'s calibration; a TUM-VI export has {} instead)",
                                camera_yaml(c).string(), c, (dso / "camchain.yaml").string()));
    }
  }
  Rig rig;
  Eigen::Isometry3d T_BI = Eigen::Isometry3d::Identity();
  if (imu == FolderImu::Required || (imu == FolderImu::IfPresent && fs::is_regular_file(imu_yaml))) {
    rig.imu = load_euroc_imu(imu_yaml.string());
    T_BI = rig.imu->T_RS;
    rig.imu->T_RS = Eigen::Isometry3d::Identity();
  }
  for (const int c : cameras) {
    CameraCalibration cam = load_euroc_camera(camera_yaml(c).string(), &rig.warnings);
    cam.T_RS = T_BI.inverse() * cam.T_RS;
    rig.cameras.push_back(cam);
  }
  rig.r_is_imu = rig.imu.has_value();
  return rig;
}

CameraCalibration load_monoslam_camera(const std::string& path) {
  if (!fs::is_regular_file(path)) throw IoError(fmt::format("{}: file not found", path));
  std::ifstream in(path);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw ConfigError(fmt::format("{}: malformed JSON: {}", path, e.what()));
  }
  const auto num = [&](const char* key) {
    if (!j.contains(key) || !j[key].is_number()) {
      throw ConfigError(fmt::format("{}: missing or non-numeric key '{}'", path, key));
    }
    return j[key].get<double>();
  };
  CameraCalibration cam;
  cam.name = "cam0";
  cam.width = image_side(num("width"), path, "width");
  cam.height = image_side(num("height"), path, "height");
  cam.rate_hz = j.contains("fps") ? num("fps") : 0.0;
  cam.fx = num("focal_length_x");
  cam.fy = num("focal_length_y");
  cam.cx = num("principal_point_x");
  cam.cy = num("principal_point_y");
  const std::string model = j.contains("model") && j["model"].is_string() ? j["model"].get<std::string>() : "wideangle";
  cam.distortion = distortion_model_from_string(model, path + ": model");
  if (cam.distortion == DistortionModel::MonoSlamOneParam) {
    const double kx = num("radial_distortion_x");
    if (j.contains("radial_distortion_y") && num("radial_distortion_y") != kx) {
      throw ConfigError(fmt::format("{}: radial_distortion_x != radial_distortion_y; the one-parameter model needs "
                                    "them equal",
                                    path));
    }
    cam.distortion_coeffs = {kx};
  }
  if (j.contains("skew") && num("skew") != 0.0) throw ConfigError(fmt::format("{}: non-zero skew is not supported", path));
  check_intrinsics(cam, path);
  cam.T_RS.linear() = Eigen::Vector3d(-1.0, -1.0, 1.0).asDiagonal();
  return cam;
}

CameraCalibration load_kitti_calib(const std::string& path, int camera) {
  LineReader in(path);
  std::string line;
  const std::string key = fmt::format("P{}:", camera);
  std::optional<std::vector<double>> P;
  while (in.next(line)) {
    const auto f = split(line, ' ');
    if (f.empty() || f[0] != key) continue;
    std::vector<double> v(f.size() - 1);
    bool ok = f.size() == 13;
    for (size_t i = 1; ok && i < f.size(); ++i) ok = parse_double(f[i], v[i - 1]);
    if (!ok) throw IoError(fmt::format("{}:{}: '{}' needs 12 numbers", path, in.line_number(), key));
    P = v;
  }
  if (!P) throw IoError(fmt::format("{}: no '{}' line", path, key));
  CameraCalibration cam;
  cam.name = fmt::format("cam{}", camera);
  cam.fx = (*P)[0];
  cam.cx = (*P)[2];
  cam.fy = (*P)[5];
  cam.cy = (*P)[6];
  for (double x : *P) {
    if (!std::isfinite(x)) throw ConfigError(fmt::format("{}: '{}' contains a non-finite number", path, key));
  }
  if (!(cam.fx > 0) || !(cam.fy > 0)) throw ConfigError(fmt::format("{}: '{}' has fx or fy <= 0", path, key));
  // P = K [I | t] with K = [fx 0 cx; 0 fy cy; 0 0 1]: t = K⁻¹ P(:, 3), and the camera sits at −t in cam0's frame.
  const double tz = (*P)[11];
  cam.T_RS.translation() =
      -Eigen::Vector3d(((*P)[3] - cam.cx * tz) / cam.fx, ((*P)[7] - cam.cy * tz) / cam.fy, tz);
  if (!cam.T_RS.translation().allFinite()) {
    throw ConfigError(fmt::format("{}: '{}' puts the camera at a non-finite position", path, key));
  }
  return cam;
}

namespace {

Eigen::Isometry3d read_T(YamlMap& m, const std::string& key, std::vector<std::string>* warnings, bool warn_far) {
  if (!m.has(key)) return Eigen::Isometry3d::Identity();
  Eigen::Matrix4d T;
  m.get_matrix(key, T);
  check_extrinsic(T, m.where(), key, warnings, warn_far);
  return to_isometry(T);
}

}  // namespace

namespace {

Rig rig_yaml(const std::string& path) {
  YamlMap root(load_yaml_lenient(path), path);
  Rig rig;
  if (!root.has("cameras") || !root.node()["cameras"].IsSequence()) {
    throw ConfigError(fmt::format("{}: 'cameras' must be a list", path));
  }
  YAML::Node cams;
  root.get("cameras", cams);
  for (size_t i = 0; i < cams.size(); ++i) {
    YamlMap m(cams[i], fmt::format("{}/cameras[{}]", path, i));
    CameraCalibration cam;
    cam.name = fmt::format("cam{}", i);
    m.get("name", cam.name);
    cam.width = m.require<int>("width");
    cam.height = m.require<int>("height");
    m.get("rate_hz", cam.rate_hz);
    Eigen::Vector4d k;
    if (!m.has("intrinsics")) throw ConfigError(fmt::format("{}: missing required key 'intrinsics'", m.where()));
    m.get_matrix("intrinsics", k);
    cam.fx = k[0];
    cam.fy = k[1];
    cam.cx = k[2];
    cam.cy = k[3];
    std::string model = "none";
    m.get("distortion_model", model);
    cam.distortion = distortion_model_from_string(model, m.where() + ": distortion_model");
    if (m.has("distortion_coeffs")) {
      Eigen::VectorXd d(distortion_coefficient_count(cam.distortion));
      m.get_matrix("distortion_coeffs", d);
      cam.distortion_coeffs.assign(d.data(), d.data() + d.size());
    }
    check_intrinsics(cam, m.where());
    cam.T_RS = read_T(m, "T_RS", &rig.warnings, true);
    m.finish();
    rig.cameras.push_back(cam);
  }
  if (root.has("imu")) {
    YamlMap m = root.child("imu");
    ImuCalibration imu;
    m.get("name", imu.name);
    imu.rate_hz = m.require<double>("rate_hz");
    imu.gyro_noise_density = m.require<double>("gyro_noise_density");
    imu.gyro_random_walk = m.require<double>("gyro_random_walk");
    imu.accel_noise_density = m.require<double>("accel_noise_density");
    imu.accel_random_walk = m.require<double>("accel_random_walk");
    if (m.has("gyro_saturation")) imu.gyro_saturation = m.require<double>("gyro_saturation");
    if (m.has("accel_saturation")) imu.accel_saturation = m.require<double>("accel_saturation");
    check_imu(imu, m.where());
    imu.T_RS = read_T(m, "T_RS", nullptr, false);
    m.finish();
    // The inertial robot's frame R is its IMU (as the EuRoC loader makes it): an IMU given off R moves R onto it,
    // T_RS(camera) = T_RI⁻¹ T_RS, so that nothing downstream has to apply the IMU's own extrinsic.
    if (!imu.T_RS.matrix().isIdentity(0.0)) {
      for (CameraCalibration& cam : rig.cameras) cam.T_RS = imu.T_RS.inverse() * cam.T_RS;
      imu.T_RS = Eigen::Isometry3d::Identity();
    }
    rig.r_is_imu = true;
    rig.imu = imu;
  }
  double t_d_s = 0.0;
  if (root.has("t_d_ns")) {
    std::int64_t t_d = 0;
    root.get("t_d_ns", t_d);
    require_bound(t_d >= -9'200'000'000'000'000'000LL && t_d <= 9'200'000'000'000'000'000LL, path, "t_d_ns",
                  static_cast<double>(t_d), "within +-9.2e18 ns (as t_d: +-9.2e9 s)");
    rig.t_d = t_d;
  }
  root.get("t_d", t_d_s);
  if (t_d_s != 0.0) rig.t_d = offset_ns(t_d_s, path, "t_d");
  root.finish();
  return rig;
}

}  // namespace

Rig load_rig_yaml(const std::string& path) {
  return translate_yaml_errors(path, [&] { return rig_yaml(path); });
}

namespace {

/// A YAML double-quoted scalar that reads back as exactly `s` (names may hold ':', '#', quotes or nothing at all).
std::string yaml_quoted(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (u < 0x20 || u == 0x7f) {
      out += fmt::format("\\x{:02x}", u);
    } else {
      out += c;
    }
  }
  return out + "\"";
}

}  // namespace

void write_rig_yaml(const std::string& path, const Rig& rig) {
  auto out = open_for_writing(path);
  const auto mat = [](const Eigen::Isometry3d& T) {
    std::string s = "[";
    for (int r = 0; r < 4; ++r) {
      s += r == 0 ? "[" : ", [";
      for (int c = 0; c < 4; ++c) s += (c ? ", " : "") + format_double(T.matrix()(r, c));
      s += "]";
    }
    return s + "]";
  };
  out << "# rtslam rig calibration (docs/datasets.md). T_RS maps sensor points into the robot frame R.\n";
  out << "t_d_ns: " << rig.t_d << "  # t_imu = t_cam + t_d\n";
  out << "cameras:\n";
  for (const auto& c : rig.cameras) {
    out << "  - name: " << yaml_quoted(c.name) << "\n    width: " << c.width << "\n    height: " << c.height
        << "\n    rate_hz: " << format_double(c.rate_hz) << "\n    intrinsics: [" << format_double(c.fx) << ", "
        << format_double(c.fy) << ", " << format_double(c.cx) << ", " << format_double(c.cy) << "]  # fx fy cx cy [px]"
        << "\n    distortion_model: " << to_string(c.distortion) << "\n    distortion_coeffs: [";
    for (size_t i = 0; i < c.distortion_coeffs.size(); ++i) out << (i ? ", " : "") << format_double(c.distortion_coeffs[i]);
    out << "]\n    T_RS: " << mat(c.T_RS) << "\n";
  }
  if (rig.imu) {
    const auto& m = *rig.imu;
    out << "imu:\n  name: " << yaml_quoted(m.name) << "\n  rate_hz: " << format_double(m.rate_hz)
        << "\n  gyro_noise_density: " << format_double(m.gyro_noise_density) << "  # rad/s/sqrt(Hz)"
        << "\n  gyro_random_walk: " << format_double(m.gyro_random_walk) << "  # rad/s^2/sqrt(Hz)"
        << "\n  accel_noise_density: " << format_double(m.accel_noise_density) << "  # m/s^2/sqrt(Hz)"
        << "\n  accel_random_walk: " << format_double(m.accel_random_walk) << "  # m/s^3/sqrt(Hz)\n";
    if (m.gyro_saturation) out << "  gyro_saturation: " << format_double(*m.gyro_saturation) << "  # rad/s\n";
    if (m.accel_saturation) out << "  accel_saturation: " << format_double(*m.accel_saturation) << "  # m/s^2\n";
    out << "  T_RS: " << mat(m.T_RS) << "\n";
  }
  close_checked(out, path);
}

namespace {

Rig calibration_by_content(const std::string& path) {
  if (to_lower(fs::path(path).extension().string()) == ".json") {
    Rig rig;
    rig.cameras.push_back(load_monoslam_camera(path));
    return rig;
  }
  const YAML::Node y = load_yaml_lenient(path);
  if (!y.IsMap()) throw ConfigError(fmt::format("{}: expected a mapping", path));
  if (y["cameras"]) return load_rig_yaml(path);
  if (y["cam0"]) return load_kalibr(path);
  if (y["sensor_type"]) {
    const std::string type = to_lower(need<std::string>(y, "sensor_type", path));
    Rig rig;
    if (type == "camera") {
      rig.cameras.push_back(load_euroc_camera(path, &rig.warnings));
      return rig;
    }
    if (type == "imu") {
      rig.imu = load_euroc_imu(path);
      return rig;
    }
    throw ConfigError(fmt::format("{}: sensor_type '{}' is not a camera or an imu", path, type));
  }
  if (y["imu0"] || y["accelerometer_noise_density"]) {
    Rig rig;
    rig.imu = load_kalibr_imu(path);
    return rig;
  }
  throw ConfigError(fmt::format("{}: not a known calibration file (rtslam 'cameras:', Kalibr 'cam0:', EuRoC "
                                "'sensor_type:', Kalibr imu 'imu0:')",
                                path));
}

}  // namespace

Rig load_calibration(const std::string& path) {
  return translate_yaml_errors(path, [&] { return calibration_by_content(path); });
}

}  // namespace rtslam::io
