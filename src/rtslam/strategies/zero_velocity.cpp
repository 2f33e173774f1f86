#include "rtslam/strategies/zero_velocity.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/strategies/active_search.hpp"

namespace rtslam::strategies {

void ZeroVelocityOptions::validate() const {
  const std::string w = "zero_velocity";
  require_bound(window_s > 0.0 && window_s <= 10.0, w, "window", window_s, "in (0, 10] s");
  require_bound(max_gyro_std > 0.0 && max_gyro_std <= 10.0, w, "max_gyro_std", max_gyro_std, "in (0, 10] rad/s");
  require_bound(max_accel_std > 0.0 && max_accel_std <= 100.0, w, "max_accel_std", max_accel_std,
                "in (0, 100] m/s²");
  require_bound(max_disparity_px > 0.0 && max_disparity_px <= 100.0, w, "max_disparity_px", max_disparity_px,
                "in (0, 100] px");
  require_bound(min_matches >= 3 && min_matches <= 1000, w, "min_matches", min_matches, "in [3, 1000]");
  require_bound(velocity_std > 0.0 && velocity_std <= 1.0, w, "velocity_std", velocity_std, "in (0, 1] m/s");
}

void read_zero_velocity(YamlMap m, ZeroVelocityOptions& o) {
  m.get("enabled", o.enabled);
  m.get("window", o.window_s);
  m.get("max_gyro_std", o.max_gyro_std);
  m.get("max_accel_std", o.max_accel_std);
  m.get("max_disparity_px", o.max_disparity_px);
  m.get("min_matches", o.min_matches);
  m.get("velocity_std", o.velocity_std);
  m.finish();
}

YAML::Node zero_velocity_to_yaml(const ZeroVelocityOptions& o) {
  YAML::Node n;
  n["enabled"] = o.enabled;
  n["window"] = o.window_s;
  n["max_gyro_std"] = o.max_gyro_std;
  n["max_accel_std"] = o.max_accel_std;
  n["max_disparity_px"] = o.max_disparity_px;
  n["min_matches"] = o.min_matches;
  n["velocity_std"] = o.velocity_std;
  return n;
}

void ZeroVelocityUpdater::add_robot(const slam::Robot& robot, const ZeroVelocityOptions& options) {
  options.validate();
  for (const Held& h : held_) {
    if (h.robot == &robot) throw ConfigError(fmt::format("zero_velocity: robot '{}' added twice", robot.name()));
  }
  // v = 0 (robot blocks [p q v ...]: v at tangent rows 6..8; the constant-velocity robot also ω = 0 at 9..11).
  const int m = robot.rest_rows();
  if (m <= 0 || 6 + m > robot.layout().tangent_size()) {
    throw ConfigError(fmt::format("zero_velocity: robot '{}' has no velocity in its state (tangent size {}) to set to "
                                  "0; turn zero_velocity off for it",
                                  robot.name(), robot.layout().tangent_size()));
  }
  Held h;
  h.robot = &robot;
  h.options = options;
  h.H = Eigen::MatrixXd::Zero(m, robot.layout().tangent_size());
  h.H.block(0, 6, m, m).setIdentity();
  h.R = options.velocity_std * options.velocity_std * Eigen::MatrixXd::Identity(m, m);
  h.y = Eigen::VectorXd::Zero(m);
  held_.push_back(std::move(h));
  displacements_.reserve(512);
}

bool ZeroVelocityUpdater::imu_at_rest(const ZeroVelocityOptions& o, const RingBuffer<slam::ImuData>& inputs,
                                      TimeNs t) const {
  // The window, or at the start of a stream what there is of it once that is a quarter of it (the images must agree
  // too; a stream that starts at rest is then held from its first frames, not after a whole window of drift).
  const TimeNs from = t - from_seconds(o.window_s);
  if (inputs.empty() || inputs.front().t > t - from_seconds(0.25 * o.window_s)) return false;
  // The spread of the readings averaged over blocks of kBlock: a body at rest on spinning rotors vibrates at tens to
  // hundreds of Hz, which the block means average out; motion changes them.
  constexpr TimeNs kBlock = 25'000'000;
  Eigen::Vector3d sg = Eigen::Vector3d::Zero(), sa = Eigen::Vector3d::Zero();
  Eigen::Vector3d qg = Eigen::Vector3d::Zero(), qa = Eigen::Vector3d::Zero();
  Eigen::Vector3d bg = Eigen::Vector3d::Zero(), ba = Eigen::Vector3d::Zero();
  int n = 0, in_block = 0;
  TimeNs block_end = t - kBlock;
  const auto close_block = [&] {
    if (in_block == 0) return;
    bg /= in_block;
    ba /= in_block;
    sg += bg;
    qg += bg.cwiseAbs2();
    sa += ba;
    qa += ba.cwiseAbs2();
    ++n;
    bg.setZero();
    ba.setZero();
    in_block = 0;
  };
  for (std::size_t k = inputs.size(); k-- > 0;) {
    const slam::ImuData& d = inputs[k];
    if (d.t > t) continue;
    if (d.t < from) break;
    while (d.t <= block_end) {
      close_block();
      block_end -= kBlock;
    }
    bg += d.m.gyro;
    ba += d.m.accel;
    ++in_block;
  }
  close_block();
  if (n < 4) return false;
  const auto spread = [n](const Eigen::Vector3d& s, const Eigen::Vector3d& q) {
    const Eigen::Vector3d mean = s / n;
    return (q / n - mean.cwiseAbs2()).cwiseMax(0.0).sum();  // Σ per-axis variances = (norm of the stds)²
  };
  return std::sqrt(spread(sg, qg)) <= o.max_gyro_std && std::sqrt(spread(sa, qa)) <= o.max_accel_std;
}

void ZeroVelocityUpdater::after_step(slam::Map& map, slam::Robot& robot, const slam::Sensor& sensor,
                                     const slam::RawData& raw, const RingBuffer<slam::ImuData>& inputs,
                                     slam::FrameStats& stats) {
  const auto* dm = dynamic_cast<const ActiveSearchDataManager*>(sensor.data_manager());
  if (dm == nullptr || sensor.id() < 0) return;  // not a camera (an absolute fix), or not attached
  after_image(map, robot, sensor.id(), raw.t, dm->last_frame(), inputs, stats);
}

void ZeroVelocityUpdater::after_image(slam::Map& map, slam::Robot& robot, int sensor_id, TimeNs t,
                                      std::span<const ActiveSearchDataManager::FrameMatch> matches,
                                      const RingBuffer<slam::ImuData>& inputs, slam::FrameStats& stats) {
  const auto it = std::find_if(held_.begin(), held_.end(), [&](const Held& h) { return h.robot == &robot; });
  if (it == held_.end() || sensor_id < 0) return;
  Held& held = *it;
  const ZeroVelocityOptions& o = held.options;
  // The image test: displacement of each landmark matched now and in this sensor's previous frame.
  const auto k = static_cast<std::size_t>(sensor_id);
  if (last_z_.size() <= k) last_z_.resize(k + 1);
  std::vector<Matched>& last = last_z_[k];  // sorted by landmark id
  displacements_.clear();
  for (const auto& m : matches) {
    if (m.landmark_id < 0 || !m.matched) continue;
    const auto at = std::lower_bound(last.begin(), last.end(), m.landmark_id,
                                     [](const Matched& a, int id) { return a.id < id; });
    if (at != last.end() && at->id == m.landmark_id) displacements_.push_back((m.z - at->z).norm());
  }
  // Remember this frame's matches only (a landmark not matched now has no displacement next frame).
  last.clear();
  for (const auto& m : matches) {
    if (m.landmark_id >= 0 && m.matched) last.push_back(Matched{m.landmark_id, m.z});
  }
  std::sort(last.begin(), last.end(), [](const Matched& a, const Matched& b) { return a.id < b.id; });
  disparity_ = -1.0;
  Verdict& still = held.verdict;
  if (static_cast<int>(displacements_.size()) >= o.min_matches) {
    auto mid = displacements_.begin() + static_cast<std::ptrdiff_t>(displacements_.size() / 2);
    std::nth_element(displacements_.begin(), mid, displacements_.end());
    disparity_ = *mid;
    still = Verdict{disparity_ <= o.max_disparity_px, t};
  }
  // Too few matches to judge: the images' previous verdict stands for up to `window` s (the IMU must still agree).
  if (!still.still || t - still.t > from_seconds(o.window_s)) return;
  if (held.last_t == t) return;  // this time's other image: the robot was told already
  if (robot.needs_inputs() && !imu_at_rest(o, inputs, t)) return;

  const int m = static_cast<int>(held.y.size());
  const filter::BlockId blocks[1] = {robot.block()};
  held.y = -map.state().mean(robot.block()).segment(7, m);  // ambient: v at 7 (and ω at 10: constant velocity)
  const filter::CorrectionResult r = map.state().correct(blocks, held.H, held.y, held.R);
  if (r.ok()) {
    held.last_t = t;
    stats.zero_velocity = true;
    ++updates_;
    robot.set_at_rest(true);  // held over the next prediction (robots with inputs; see Robot::set_at_rest)
    return;
  }
  if (refused_++ == 0) {
    logger("slam")->warn("t = {:.3f} s: zero velocity: the filter refused the update of robot '{}' ({}); counted, "
                         "later refusals are not logged",
                         to_seconds(t), robot.name(), filter::to_string(r.status));
  }
}

void ZeroVelocityUpdater::on_start(const slam::Robot& robot, const slam::RobotStart& /*start*/) {
  const auto it = std::find_if(held_.begin(), held_.end(), [&](const Held& h) { return h.robot == &robot; });
  if (it == held_.end()) return;
  it->verdict = Verdict{};
  it->last_t = std::numeric_limits<TimeNs>::min();
  for (const auto& sensor : robot.sensors()) {
    if (sensor->id() >= 0 && static_cast<std::size_t>(sensor->id()) < last_z_.size()) {
      last_z_[static_cast<std::size_t>(sensor->id())].clear();
    }
  }
}

}  // namespace rtslam::strategies
