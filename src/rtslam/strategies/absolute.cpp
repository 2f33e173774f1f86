#include "rtslam/strategies/absolute.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/models/sensors/absolute.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/robot.hpp"
#include "rtslam/strategies/active_search.hpp"

namespace rtslam::strategies {

namespace {

constexpr double kDeg = M_PI / 180.0;
constexpr double kChi2_999_3 = 16.266;  // χ² quantiles at 99.9 %, 3 and 6 dof
constexpr double kChi2_999_6 = 22.458;
// Position alignment: the fixes' yaw replaces the robot's own (arbitrary) start yaw in the rigid moves before the
// hand-over once its linearized std is below this (above, σ/√spread no longer describes the estimate).
constexpr double kProvisionalYawStd = 45.0 * kDeg;

Eigen::Matrix3d yaw_rotation(double psi) { return Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ()).toRotationMatrix(); }

}  // namespace

math::Pose AbsoluteSensorOptions::T_RS() const {
  return {math::exp_so3(rotation_deg * kDeg), lever_arm};
}

double AbsoluteSensorOptions::gate_for(int dof) const {
  if (gate > 0.0) return gate;
  return dof == 3 ? kChi2_999_3 : kChi2_999_6;
}

void AbsoluteSensorOptions::validate(const std::string& w) const {
  require_bound(sigma_m > 0.0 && sigma_m <= 1e4, w, "sigma", sigma_m, "in (0, 1e4] m");
  require_bound(sigma_deg > 0.0 && sigma_deg <= 180.0, w, "sigma_deg", sigma_deg, "in (0, 180] deg");
  for (int i = 0; i < 3; ++i) {
    require_bound(std::abs(lever_arm[i]) <= 100.0, w, "lever_arm", lever_arm[i], "in [-100, 100] m per axis");
    require_bound(std::abs(rotation_deg[i]) <= 360.0, w, "rotation_deg", rotation_deg[i], "in [-360, 360] deg");
  }
  require_bound(gate >= 0.0 && gate <= 1e6, w, "gate", gate, "in [0, 1e6] (0: the χ² 99.9 % quantile)");
  if (world != "align" && world != "start")
    throw ConfigError(fmt::format("{}: world = '{}' must be align or start", w, world));
  require_bound(align_yaw_std_deg > 0.0 && align_yaw_std_deg <= 45.0, w, "align_yaw_std_deg", align_yaw_std_deg,
                "in (0, 45] deg");
  require_bound(align_min_fixes >= 2 && align_min_fixes <= 100000, w, "align_min_fixes", align_min_fixes,
                "in [2, 100000]");
}

void read_absolute_sensor(YamlMap m, AbsoluteSensorOptions& o, bool pose) {
  m.get("enabled", o.enabled);
  m.get("sigma", o.sigma_m);
  if (m.has("lever_arm")) m.get_matrix("lever_arm", o.lever_arm);
  m.get("gate", o.gate);
  m.get("world", o.world);
  if (pose) {
    m.get("sigma_deg", o.sigma_deg);
    if (m.has("rotation_deg")) m.get_matrix("rotation_deg", o.rotation_deg);
  } else {
    m.get("align_yaw_std_deg", o.align_yaw_std_deg);
    m.get("align_min_fixes", o.align_min_fixes);
  }
  m.finish();  // validated with the whole configuration (ImageSlamOptions::validate), which names the file
}

YAML::Node absolute_sensor_to_yaml(const AbsoluteSensorOptions& o, bool pose) {
  YAML::Node n;
  n["enabled"] = o.enabled;
  n["sigma"] = o.sigma_m;
  n["lever_arm"] = std::vector<double>{o.lever_arm.x(), o.lever_arm.y(), o.lever_arm.z()};
  n["gate"] = o.gate;
  n["world"] = o.world;
  if (pose) {
    n["sigma_deg"] = o.sigma_deg;
    n["rotation_deg"] = std::vector<double>{o.rotation_deg.x(), o.rotation_deg.y(), o.rotation_deg.z()};
  } else {
    n["align_yaw_std_deg"] = o.align_yaw_std_deg;
    n["align_min_fixes"] = o.align_min_fixes;
  }
  return n;
}

AbsoluteDataManager::AbsoluteDataManager(AbsoluteSensorOptions options, bool gravity_aligned)
    : o_(std::move(options)), gravity_aligned_(gravity_aligned) {
  o_.validate("absolute sensor");
  aligned_ = o_.world == "start";
  H_.setZero(6, filter::StateOptions{}.max_block_tangent);
  R_.setZero(6, 6);
  y_.setZero(6);
  fixes_.reserve(std::max<std::size_t>(static_cast<std::size_t>(o_.align_min_fixes), 1024));
  predicted_.reserve(fixes_.capacity());
}

void AbsoluteDataManager::apply(slam::Map& map, const slam::WorldChange& change) {
  const std::string why = slam::change_world_frame(map, change, [](slam::Landmark& l, const math::Pose& T_GW) {
    // The view a landmark's patch was taken from is a pose in W.
    if (const PointDescriptor* d = point_descriptor(l)) {
      auto moved = std::make_shared<PointDescriptor>(*d);
      moved->T_WS0 = T_GW * d->T_WS0;
      l.descriptor = PointDescriptorPtr(std::move(moved));
    }
  });
  if (!why.empty()) throw ConfigError(fmt::format("absolute sensor: cannot move the map into the sensor's frame: {}", why));
}

void AbsoluteDataManager::align_pose(slam::Map& map, const math::Pose& z, const math::Pose& h,
                                     const Eigen::Matrix<double, 6, 6>& R, TimeNs t) {
  // The whole rotation, also for the inertial robot: its world frame is gravity-aligned only up to its gravity
  // estimate (a state), which turns with the map (slam::change_world_frame).
  slam::WorldChange c;
  c.T_GW = z * h.inverse();
  c.center_G = z.p;
  // The fix's [δp δθ] (attitude: right perturbation of q_GM) as [δc δφ] (rotation in G): δφ = R_GM δθ.
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Identity();
  A.bottomRightCorner<3, 3>() = z.q.toRotationMatrix();
  c.cov = A * R * A.transpose();
  apply(map, c);
  alignment_ = c;
  aligned_ = true;
  aligned_at_ = t;
  logger("slam")->info("t = {:.3f} s: pose sensor: map moved into the sensor's frame (rotated {:.1f} deg, shifted "
                       "{:.2f} m)", to_seconds(t), math::log_so3(c.T_GW.q).norm() / kDeg, c.T_GW.p.norm());
}

void AbsoluteDataManager::align_position(slam::Map& map, const Eigen::Vector3d& z, const Eigen::Vector3d& h,
                                         double sigma, TimeNs t) {
  // Every fix before the hand-over: the rigid yaw-and-translation move that best puts the predicted antenna
  // positions (in the start frame W0: h0 = T_moved⁻¹ h) onto the fixes, applied to the map without any claimed
  // uncertainty (a rigid move is exact: no linearization of a large yaw correction in the filter).
  fixes_.push_back(z);
  predicted_.push_back(T_moved_.inverse_transform(h));
  const auto n = static_cast<double>(fixes_.size());
  Eigen::Vector3d zbar = Eigen::Vector3d::Zero(), hbar = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < fixes_.size(); ++k) {
    zbar += fixes_[k] / n;
    hbar += predicted_[k] / n;
  }
  double spread = 0.0, s_sin = 0.0, s_cos = 0.0;
  for (std::size_t k = 0; k < fixes_.size(); ++k) {
    const Eigen::Vector2d a = (predicted_[k] - hbar).head<2>(), b = (fixes_[k] - zbar).head<2>();
    spread += a.squaredNorm();
    s_sin += a.x() * b.y() - a.y() * b.x();
    s_cos += a.x() * b.x() + a.y() * b.y();
  }
  const double yaw_std = spread > 0.0 ? sigma / std::sqrt(spread) : M_PI;
  const bool enough = fixes_.size() >= static_cast<std::size_t>(o_.align_min_fixes);
  const Eigen::Matrix3d R_moved = T_moved_.q.toRotationMatrix();
  double psi = std::atan2(R_moved(1, 0), R_moved(0, 0));  // the yaw so far (the robot's own until the fixes tell)
  if (enough && yaw_std <= kProvisionalYawStd) psi = std::atan2(s_sin, s_cos);
  math::Pose target;
  target.q = Eigen::Quaterniond(yaw_rotation(psi));
  target.p = zbar - target.q * hbar;
  const bool hand_over = enough && yaw_std <= o_.align_yaw_std_deg * kDeg;
  slam::WorldChange c;
  c.T_GW = target * T_moved_.inverse();
  c.T_GW.q.normalize();
  c.center_G = zbar;
  if (hand_over) {  // from now on the filter refines yaw and translation: their uncertainty enters the map
    c.cov.topLeftCorner<3, 3>() = (sigma * sigma / n) * Eigen::Matrix3d::Identity();
    c.cov(5, 5) = yaw_std * yaw_std;
  }
  apply(map, c);
  T_moved_ = target;
  if (!hand_over) return;
  alignment_.T_GW = target;
  alignment_.center_G = zbar;
  alignment_.cov = c.cov;
  aligned_ = true;
  aligned_at_ = t;
  logger("slam")->info("t = {:.3f} s: position sensor: map aligned with {} fixes (yaw {:.1f} ± {:.1f} deg from the "
                       "start frame, shift {:.2f} m); the filter takes the fixes from now on",
                       to_seconds(t), fixes_.size(), psi / kDeg, yaw_std / kDeg, target.p.norm());
  fixes_.clear();
  predicted_.clear();
}

void AbsoluteDataManager::process(slam::Map& map, slam::Sensor& sensor, const slam::RawData& raw, long /*frame*/,
                                  slam::FrameStats& stats) {
  const auto* abs_sensor = dynamic_cast<const slam::AbsoluteSensor*>(&sensor);
  RTSLAM_CHECK(abs_sensor != nullptr, "the absolute data manager serves absolute sensors only");
  slam::Robot& robot = sensor.robot();
  filter::State& state = map.state();
  const int n = state.block(robot.block()).tangent_size();
  const math::Pose T_WR = robot.pose(state.mean_vector());
  const filter::BlockId blocks[1] = {robot.block()};
  int m = 0;
  if (abs_sensor->kind() == slam::AbsoluteSensor::Kind::Position) {
    const auto* d = dynamic_cast<const slam::PositionData*>(&raw);
    RTSLAM_CHECK(d != nullptr, "a position sensor takes PositionData");
    Eigen::Matrix<double, 3, 6> J;
    const Eigen::Vector3d h = models::absolute_position(T_WR, sensor.T_RS().p, &J);
    const Eigen::Matrix3d R = d->has_cov ? d->cov : Eigen::Matrix3d::Identity() * (o_.sigma_m * o_.sigma_m);
    if (!aligned_) {
      RTSLAM_CHECK(gravity_aligned_, "position sensor alignment needs a gravity-aligned robot");
      align_position(map, d->p_WA, h, std::sqrt(R.trace() / 3.0), raw.t);
      return;
    }
    m = 3;
    y_.head<3>() = d->p_WA - h;
    H_.topLeftCorner(3, n).setZero();
    H_.topLeftCorner<3, 6>() = J;
    R_.topLeftCorner<3, 3>() = R;
  } else {
    const auto* d = dynamic_cast<const slam::PoseData*>(&raw);
    RTSLAM_CHECK(d != nullptr, "a pose sensor takes PoseData");
    Eigen::Matrix<double, 6, 6> J_TWM_TWR, J_y_h;
    const math::Pose h = models::absolute_pose(T_WR, sensor.T_RS(), &J_TWM_TWR);
    Eigen::Matrix<double, 6, 6> R = Eigen::Matrix<double, 6, 6>::Zero();
    if (d->has_cov) {
      R = d->cov;
    } else {
      R.topLeftCorner<3, 3>().diagonal().setConstant(o_.sigma_m * o_.sigma_m);
      R.bottomRightCorner<3, 3>().diagonal().setConstant(std::pow(o_.sigma_deg * kDeg, 2));
    }
    if (!aligned_) {
      align_pose(map, d->T_WM, h, R, raw.t);
      return;
    }
    m = 6;
    y_.head<6>() = models::pose_innovation(d->T_WM, h, &J_y_h);
    H_.topLeftCorner(6, n).setZero();
    H_.topLeftCorner<6, 6>() = -J_y_h * J_TWM_TWR;
    R_.topLeftCorner<6, 6>() = R;
  }
  const filter::CorrectionResult r =
      state.correct(blocks, H_.topLeftCorner(m, n), y_.head(m), R_.topLeftCorner(m, m), o_.gate_for(m));
  last_nis_ = r.mahalanobis2;
  if (r.ok()) {
    ++stats.absolute_updates;
    ++updates_;
  } else {
    ++stats.absolute_rejected;
    ++rejected_;
    if (r.status != filter::CorrectionResult::Status::Gated) ++stats.refused;
    logger("slam")->debug("t = {:.3f} s: absolute fix not applied ({}, NIS {:.1f})", to_seconds(raw.t),
                          filter::to_string(r.status), r.mahalanobis2);
  }
}

}  // namespace rtslam::strategies
