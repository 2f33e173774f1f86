#include "rtslam/pipeline/known_landmarks.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/sensor.hpp"
#include "rtslam/strategies/active_search.hpp"

namespace rtslam::pipeline {

namespace {

Eigen::VectorXd json_vector(const nlohmann::json& j, const std::string& where, int n) {
  if (!j.is_array() || static_cast<int>(j.size()) != n) {
    throw ConfigError(fmt::format("{}: expected a list of {} numbers", where, n));
  }
  Eigen::VectorXd v(n);
  for (int i = 0; i < n; ++i) {
    if (!j[static_cast<size_t>(i)].is_number()) throw ConfigError(fmt::format("{}[{}]: not a number", where, i));
    v[i] = j[static_cast<size_t>(i)].get<double>();
    if (!std::isfinite(v[i])) throw ConfigError(fmt::format("{}[{}] = {} must be finite", where, i, v[i]));
  }
  return v;
}

}  // namespace

void check_initial_state(const Eigen::VectorXd& x, const Eigen::MatrixXd& P, int q_index, const std::string& where) {
  if (!x.allFinite()) throw ConfigError(fmt::format("{}: xv holds a non-finite number", where));
  const double qn = x.segment<4>(q_index).norm();
  require_bound(std::abs(qn - 1.0) <= kUnitQuaternionTolerance, where,
                fmt::format("|q| (xv[{}..{}], w x y z)", q_index, q_index + 3), qn,
                fmt::format("1 within {:g} (a unit quaternion)", kUnitQuaternionTolerance));
  if (P.rows() != P.cols() || !P.allFinite()) throw ConfigError(fmt::format("{}: pxx must be square and finite", where));
  const double scale = std::max(P.cwiseAbs().maxCoeff(), 1e-300);
  const double asym = (P - P.transpose()).cwiseAbs().maxCoeff();
  require_bound(asym <= 1e-9 * scale, where, "max |pxx - pxxᵀ|", asym, "<= 1e-9 max |pxx| (symmetric)");
  // Positive semi-definite: a zero variance is a known value (the gauge), a negative eigenvalue is an error.
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (P + P.transpose()), Eigen::EigenvaluesOnly);
  const double lowest = eig.eigenvalues().minCoeff();
  require_bound(lowest >= -1e-9 * scale, where, "smallest eigenvalue of pxx", lowest,
                ">= 0 (a covariance is positive semi-definite)");
}

KnownLandmarkSet load_known_landmarks(const std::string& folder, const std::string& convention) {
  if (convention != "scenelib" && convention != "robot") {
    throw ConfigError(fmt::format("known landmarks: convention '{}' must be robot or scenelib", convention));
  }
  std::error_code ec;
  if (!std::filesystem::is_directory(folder, ec)) {
    throw IoError(fmt::format("{}: known landmarks: not a folder (it holds initial_state.json and the patches)",
                              folder));
  }
  const std::string path = folder + "/initial_state.json";
  if (!std::filesystem::is_regular_file(path, ec)) throw IoError(fmt::format("{}: file not found", path));
  std::ifstream in(path);
  if (!in) throw IoError(fmt::format("{}: cannot open", path));
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw IoError(fmt::format("{}: not valid JSON ({})", path, e.what()));
  }
  if (!j.contains("xv") || !j.contains("pxx") || !j.contains("features")) {
    throw ConfigError(fmt::format("{}: needs keys xv, pxx and features", path));
  }
  const Eigen::VectorXd xv = json_vector(j["xv"], path + ": xv", 13);
  Eigen::MatrixXd pxx(13, 13);
  if (!j["pxx"].is_array() || j["pxx"].size() != 13) throw ConfigError(fmt::format("{}: pxx must be 13x13", path));
  for (int r = 0; r < 13; ++r) pxx.row(r) = json_vector(j["pxx"][static_cast<size_t>(r)], path + ": pxx row", 13);
  check_initial_state(xv, pxx, 3, path);

  // Frame change of the camera: S_ours = S_file · F (F = diag(−1, −1, 1) for SceneLib, a rotation by π about z).
  const Eigen::Matrix3d F = convention == "scenelib" ? Eigen::Vector3d(-1, -1, 1).asDiagonal().toDenseMatrix()
                                                     : Eigen::Matrix3d::Identity();
  const Eigen::Quaterniond q_file = math::quat_from_wxyz(xv.segment<4>(3)).normalized();
  const Eigen::Quaterniond q_ours = (q_file * Eigen::Quaterniond(F)).normalized();
  KnownLandmarkSet set;
  set.robot_mean = Eigen::VectorXd::Zero(13);
  set.robot_mean.head<3>() = xv.head<3>();
  set.robot_mean.segment<4>(3) = math::quat_to_wxyz(q_ours);
  set.robot_mean.segment<3>(7) = xv.segment<3>(7);        // v in W
  set.robot_mean.segment<3>(10) = F * xv.segment<3>(10);  // ω in the camera frame
  // Tangent covariance: δθ_file = 2 vec(q̂⁻¹ ⊗ δq) (M, 3x4 over [w x y z]), δθ_ours = Fᵀ δθ_file.
  const Eigen::Vector4d qc = math::quat_to_wxyz(q_file.conjugate());
  Eigen::Matrix4d Lq;  // left multiplication by q̂⁻¹ on [w x y z]
  const double w = qc[0], x = qc[1], y = qc[2], z = qc[3];
  Lq << w, -x, -y, -z, x, w, -z, y, y, z, w, -x, z, -y, x, w;
  const Eigen::Matrix<double, 3, 4> M = F.transpose() * 2.0 * Lq.bottomRows<3>();
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(12, 13);  // tangent ← ambient
  J.block<3, 3>(0, 0).setIdentity();
  J.block<3, 4>(3, 3) = M;
  J.block<3, 3>(6, 7).setIdentity();
  J.block<3, 3>(9, 10) = F;
  set.robot_cov = J * pxx * J.transpose();

  const auto& feats = j["features"];
  if (!feats.is_array() || feats.empty()) throw ConfigError(fmt::format("{}: features must be a non-empty list", path));
  for (size_t i = 0; i < feats.size(); ++i) {
    set.points_W.push_back(json_vector(feats[i]["yi"], fmt::format("{}: features[{}].yi", path, i), 3));
    const std::string patch_path = fmt::format("{}/known_patch{}.pgm", folder, i);
    const cv::Mat m = io::codecs::imread(patch_path, cv::IMREAD_GRAYSCALE);
    if (m.empty()) throw IoError(fmt::format("{}: cannot read the patch image", patch_path));
    if (m.rows != m.cols || m.rows % 2 == 0) {
      throw DataError(fmt::format("{}: patch is {}x{}, must be an odd square", patch_path, m.cols, m.rows));
    }
    vision::Image img(m.cols, m.rows);
    for (int v = 0; v < m.rows; ++v)
      for (int u = 0; u < m.cols; ++u) img.at(u, v) = m.at<std::uint8_t>(v, u);
    set.patches.push_back(std::move(img));
  }
  return set;
}

int add_known_landmarks(slam::Map& map, slam::Sensor& sensor, const KnownLandmarkSet& set) {
  const auto* cam = dynamic_cast<const slam::PinholeSensor*>(&sensor);
  if (cam == nullptr) throw ConfigError("known landmarks need a pinhole camera");
  const models::PinholeCamera& camera = cam->camera();
  const auto& in = camera.intrinsics();
  const math::Pose T_WS = sensor.pose_in_world(map.state().mean_vector());
  int added = 0;
  for (size_t i = 0; i < set.points_W.size(); ++i) {
    const Eigen::Vector3d p_S = T_WS.inverse_transform(set.points_W[i]);
    Eigen::Vector2d z;
    if (!(p_S.z() > 0.0) || !camera.project(p_S, z) || !camera.in_image(z, 0.0)) continue;
    Eigen::Vector2d xy_d;
    Eigen::Matrix2d Jd;
    if (!camera.distort(p_S.head<2>() / p_S.z(), xy_d, &Jd)) continue;
    // Known points define the world: a tiny covariance only (zero variances are refused by the corrections).
    const Eigen::Matrix3d Q = 1e-10 * Eigen::Matrix3d::Identity();
    const Eigen::MatrixXd J0(3, 0);
    slam::Landmark* l = map.add_landmark(filter::BlockLayout::euclidean(3), set.points_W[i], {}, J0, Q,
                                         [](int id, filter::BlockId block) {
                                           return std::make_unique<slam::EuclideanPointLandmark>(id, block);
                                         });
    if (l == nullptr) break;
    auto desc = std::make_shared<strategies::PointDescriptor>();
    desc->patch = set.patches[i];
    desc->z0_px = z;
    desc->patch_centre_px = z;  // the file set's patches are centred on the point's projection
    const Eigen::Vector2d f(in.fx, in.fy);
    desc->J_dist_undist_0 = f.asDiagonal() * Jd * f.cwiseInverse().asDiagonal();
    desc->T_WS0 = T_WS;
    l->descriptor = strategies::PointDescriptorPtr(std::move(desc));
    ++added;
  }
  return added;
}

}  // namespace rtslam::pipeline
