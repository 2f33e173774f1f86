#include "rtslam/strategies/planar_motion.hpp"

#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/robot.hpp"

namespace rtslam::strategies {

void PlanarMotionOptions::validate() const {
  const std::string w = "planar_motion";
  const double norm = up.norm();
  if (!(up.allFinite() && norm > 1e-9)) {
    throw ConfigError(
        fmt::format("{}: up = [{}, {}, {}] must be a non-zero, finite robot-frame axis", w, up.x(), up.y(), up.z()));
  }
  require_bound(height_std > 0.0 && height_std <= 10.0, w, "height_std", height_std, "in (0, 10] m");
  require_bound(tilt_std > 0.0 && tilt_std <= 1.0, w, "tilt_std", tilt_std, "in (0, 1] rad");
}

void read_planar_motion(YamlMap m, PlanarMotionOptions& o) {
  m.get("enabled", o.enabled);
  if (m.has("up")) m.get_matrix("up", o.up);
  m.get("height_std", o.height_std);
  m.get("tilt_std", o.tilt_std);
  m.finish();  // validated with the whole configuration (ImageSlamOptions::validate), which names the file
}

YAML::Node planar_motion_to_yaml(const PlanarMotionOptions& o) {
  YAML::Node n;
  n["enabled"] = o.enabled;
  n["up"] = std::vector<double>{o.up.x(), o.up.y(), o.up.z()};
  n["height_std"] = o.height_std;
  n["tilt_std"] = o.tilt_std;
  return n;
}

namespace {
// Two unit vectors completing n (unit) to an orthonormal basis: the plane's directions.
void plane_basis(const Eigen::Vector3d& n, Eigen::Vector3d& t1, Eigen::Vector3d& t2) {
  const Eigen::Vector3d a = std::abs(n.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  t1 = (a - a.dot(n) * n).normalized();
  t2 = n.cross(t1);
}
}  // namespace

void planar_motion_measurement(const Eigen::Vector3d& p, const Eigen::Matrix3d& R_WR, const Eigen::Vector3d& up,
                               const Eigen::Vector3d& n, const Eigen::Vector3d& p0, Eigen::Vector3d& h,
                               Eigen::Matrix<double, 3, 6>& H) {
  Eigen::Vector3d t1, t2;
  plane_basis(n, t1, t2);
  const Eigen::Vector3d u = R_WR * up;  // the robot's up axis in the world
  h << n.dot(p - p0), t1.dot(u), t2.dot(u);
  // ∂/∂δp: nᵀ for the height; ∂(tᵢᵀ R Exp(δθ) up)/∂δθ = −tᵢᵀ R [up]× (right perturbation).
  const Eigen::Matrix3d R_up = R_WR * math::skew(up);
  H.setZero();
  H.block<1, 3>(0, 0) = n.transpose();
  H.block<1, 3>(1, 3) = -t1.transpose() * R_up;
  H.block<1, 3>(2, 3) = -t2.transpose() * R_up;
}

PlanarMotionUpdater::PlanarMotionUpdater(PlanarMotionOptions options) : o_(std::move(options)) {
  o_.validate();
  up_ = o_.up.normalized();
  R_ =
      Eigen::Vector3d(o_.height_std * o_.height_std, o_.tilt_std * o_.tilt_std, o_.tilt_std * o_.tilt_std).asDiagonal();
  y_.resize(3);
}

std::optional<PlanarMotionUpdater::Plane> PlanarMotionUpdater::plane(int robot_id) const {
  if (robot_id < 0 || static_cast<std::size_t>(robot_id) >= planes_.size()) return std::nullopt;
  return planes_[static_cast<std::size_t>(robot_id)];
}

void PlanarMotionUpdater::after_step(slam::Map& map, slam::Robot& robot, const slam::Sensor& /*sensor*/,
                                     const slam::RawData& raw, const RingBuffer<slam::ImuData>& /*inputs*/,
                                     slam::FrameStats& /*stats*/) {
  if (!o_.enabled) return;
  const auto id = static_cast<std::size_t>(robot.id());
  if (planes_.size() <= id) {
    planes_.resize(id + 1);
    last_t_.resize(id + 1, std::numeric_limits<TimeNs>::min());
  }
  if (raw.t == last_t_[id]) return;  // this time's images already told it
  last_t_[id] = raw.t;
  const math::Pose T = robot.pose();
  if (!planes_[id]) {  // the first image: the plane the robot is on
    planes_[id] = Plane{(T.q * up_).normalized(), T.p};
    const Plane& pl = *planes_[id];
    logger("slam")->info(
        "planar motion: robot '{}' held on the plane through ({:.3f}, {:.3f}, {:.3f}) with normal ({:.3f}, {:.3f}, "
        "{:.3f}) (world frame): height std {} m, tilt std {} rad",
        robot.name(), pl.p0.x(), pl.p0.y(), pl.p0.z(), pl.n.x(), pl.n.y(), pl.n.z(), o_.height_std, o_.tilt_std);
    return;
  }
  const Plane& pl = *planes_[id];
  const int n = robot.layout().tangent_size();
  if (H_.rows() != 3 || H_.cols() != n) H_ = Eigen::MatrixXd::Zero(3, n);  // once per robot model
  Eigen::Vector3d h;
  Eigen::Matrix<double, 3, 6> J;
  planar_motion_measurement(T.p, T.q.toRotationMatrix(), up_, pl.n, pl.p0, h, J);
  H_.leftCols<6>() = J;
  y_ = -h;
  const filter::BlockId blocks[1] = {robot.block()};
  if (map.state().correct(blocks, H_, y_, R_).ok()) {
    ++updates_;
  } else {
    ++refused_;
  }
}

}  // namespace rtslam::strategies
