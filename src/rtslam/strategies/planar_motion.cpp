#include "rtslam/strategies/planar_motion.hpp"

#include <algorithm>
#include <cmath>

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

void PlanarMotionUpdater::add_robot(const slam::Robot& robot, const PlanarMotionOptions& options) {
  options.validate();
  Held h;
  h.robot = &robot;
  h.options = options;
  h.up = options.up.normalized();
  const int n = robot.layout().tangent_size();
  h.H = Eigen::MatrixXd::Zero(3, n);
  h.R = Eigen::Vector3d(options.height_std * options.height_std, options.tilt_std * options.tilt_std,
                        options.tilt_std * options.tilt_std)
            .asDiagonal();
  h.y = Eigen::VectorXd::Zero(3);
  held_.push_back(std::move(h));
}

std::optional<PlanarMotionUpdater::Plane> PlanarMotionUpdater::plane(const slam::Robot& robot) const {
  for (const Held& h : held_) {
    if (h.robot == &robot) return h.plane;
  }
  return std::nullopt;
}

void PlanarMotionUpdater::after_step(slam::Map& map, slam::Robot& robot, const slam::Sensor& sensor,
                                     const slam::RawData& raw, const RingBuffer<slam::ImuData>& /*inputs*/,
                                     slam::FrameStats& /*stats*/) {
  if (!sensor.observes_landmarks()) return;  // after images only: an absolute fix's rate is not the plane's
  const auto it = std::find_if(held_.begin(), held_.end(), [&](const Held& h) { return h.robot == &robot; });
  if (it == held_.end()) return;
  Held& held = *it;
  const math::Pose T = robot.pose();
  if (!held.plane) {  // the first image: the plane the robot is on
    held.plane = Plane{(T.q * held.up).normalized(), T.p};
    held.last_t = raw.t;
    const Plane& pl = *held.plane;
    logger("slam")->info(
        "planar motion: robot '{}' held on the plane through ({:.3f}, {:.3f}, {:.3f}) with normal ({:.3f}, {:.3f}, "
        "{:.3f}) (world frame): height std {} m, tilt std {} rad",
        robot.name(), pl.p0.x(), pl.p0.y(), pl.p0.z(), pl.n.x(), pl.n.y(), pl.n.z(), held.options.height_std,
        held.options.tilt_std);
    return;
  }
  if (raw.t == held.last_t) return;  // this time's other image: the robot was told already
  held.last_t = raw.t;
  Eigen::Vector3d h;
  Eigen::Matrix<double, 3, 6> J;
  planar_motion_measurement(T.p, T.q.toRotationMatrix(), held.up, held.plane->n, held.plane->p0, h, J);
  held.H.leftCols<6>() = J;
  held.y = -h;
  const filter::BlockId blocks[1] = {robot.block()};
  const filter::CorrectionResult r = map.state().correct(blocks, held.H, held.y, held.R);
  if (r.ok()) {
    ++updates_;
    return;
  }
  if (refused_++ == 0) {
    logger("slam")->warn("t = {:.3f} s: planar motion: the filter refused the update of robot '{}' ({}); counted, "
                         "later refusals are not logged",
                         to_seconds(raw.t), robot.name(), filter::to_string(r.status));
  }
}

void PlanarMotionUpdater::on_start(const slam::Robot& robot, const slam::RobotStart& /*start*/) {
  for (Held& h : held_) {
    if (h.robot == &robot) h.last_t = std::numeric_limits<TimeNs>::min();
  }
}

}  // namespace rtslam::strategies
