#pragma once
// Continuous-time trajectories of the robot frame R (the IMU body) in the world W, with exact derivatives.
//
// A trajectory gives, at any time t inside [t_begin, t_end]:
//   q_WR, p_WR      the pose T_WR (p_W = R(q_WR) p_R + p_WR),
//   v_WR, a_WR      velocity and acceleration of R's origin in W (m/s, m/s^2),
//   w_R, dw_R       body angular rate and its time derivative, both in R (rad/s, rad/s^2):
//                   d/dt R_WR = R_WR [w_R]x.
// World convention: z up, gravity g_W = (0, 0, -g). The robot body follows EuRoC's MAV: at "level" attitude its
// x axis points up and its z axis (≈ the camera's optical axis, EuRoC T_BS) points horizontally, so the synthetic
// presets look at the room walls.
//
// Kinds:
//  - WaveTrajectory: every position coordinate and the yaw/pitch/roll angles are sums of enveloped sinusoids
//    (analytic derivatives). `handheld` and `high-dynamic` presets are built on it.
//  - SplineTrajectory: a uniform cumulative cubic B-spline on SO(3) x R^3 whose control poses are the recorded
//    poses resampled at the knot spacing (an approximating, hence smoothing, spline), for `follow:FILE`.
#include <array>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "rtslam/core/random.hpp"
#include "rtslam/core/time.hpp"
#include "rtslam/core/trajectory.hpp"

namespace rtslam::sim {

/// The full kinematic state of R at time t (see the header comment for frames and units).
struct KinematicState {
  TimeNs t = 0;
  Eigen::Quaterniond q_WR = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_WR = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_WR = Eigen::Vector3d::Zero();
  Eigen::Vector3d a_WR = Eigen::Vector3d::Zero();
  Eigen::Vector3d w_R = Eigen::Vector3d::Zero();
  Eigen::Vector3d dw_R = Eigen::Vector3d::Zero();
};

/// A trajectory with exact first and second derivatives, defined on [t_begin(), t_end()] (clamped outside).
class ContinuousTrajectory {
 public:
  virtual ~ContinuousTrajectory() = default;
  virtual KinematicState at(TimeNs t) const = 0;
  virtual TimeNs t_begin() const = 0;
  virtual TimeNs t_end() const = 0;
  /// A short description for logs ("handheld(seed=3)", "follow:MH_01_easy.txt").
  virtual std::string describe() const = 0;
};

/// One sinusoid a·sin(2π f (t − t_on) + φ) multiplied by a C² envelope that rises over [t_on, t_on + ramp] and
/// falls over [t_off − ramp, t_off] (smootherstep), zero outside [t_on, t_off]. Times in seconds from t_begin.
struct Wave {
  double amplitude = 0.0;
  double freq_hz = 0.0;
  double phase_rad = 0.0;
  double t_on_s = 0.0;
  double t_off_s = 1e9;
  double ramp_s = 0.0;
};

/// A scalar signal: offset + Σ waves, with its first two derivatives.
struct WaveChannel {
  double offset = 0.0;
  std::vector<Wave> waves;
  /// Value at t (s), with first and second derivatives.
  double eval(double t_s, double& d1, double& d2) const;
};

/// Position (x, y, z in W, m) and attitude as yaw/pitch/roll channels (rad):
/// R_WR = Rz(yaw) Ry(pitch) Rx(roll) R_base, with R_base mapping R's x to W's z (up) and R's z to W's x.
struct WaveTrajectoryParams {
  std::array<WaveChannel, 3> position;
  WaveChannel yaw, pitch, roll;
  TimeNs t_begin = 0;
  double duration_s = 60.0;
  /// Start at rest: the channels are evaluated at a warped time τ(t) with τ' rising smoothly (smootherstep) from
  /// 0 to 1 over the first warmup_s seconds, so velocity and acceleration start at exactly zero. 0 = no warm-up.
  double warmup_s = 0.0;
  std::string name = "waves";
};

class WaveTrajectory final : public ContinuousTrajectory {
 public:
  explicit WaveTrajectory(WaveTrajectoryParams params);
  KinematicState at(TimeNs t) const override;
  TimeNs t_begin() const override { return params_.t_begin; }
  TimeNs t_end() const override { return params_.t_begin + from_seconds(params_.duration_s); }
  std::string describe() const override { return params_.name; }
  const WaveTrajectoryParams& params() const { return params_; }

  /// R_base: the robot's attitude at yaw = pitch = roll = 0 (x up, z horizontal along W's x).
  static Eigen::Matrix3d base_rotation();

 private:
  WaveTrajectoryParams params_;
};

/// Cumulative cubic B-spline on SO(3) x R^3 (uniform knots). Control pose k sits at t0 + k·dt; the spline is
/// defined on [t0 + dt, t0 + (N − 2)·dt] for N control poses (which t_begin/t_end report).
class SplineTrajectory final : public ContinuousTrajectory {
 public:
  /// Control poses T_WR_k at times t0 + k·dt; needs at least 4. Quaternion signs are made continuous.
  SplineTrajectory(TimeNs t0, TimeNs dt, std::vector<Eigen::Quaterniond> q_WR, std::vector<Eigen::Vector3d> p_WR,
                   std::string name);
  /// Resamples a recorded trajectory (sorted by time, >= 2 poses) at knot spacing dt (linear position, slerp
  /// orientation) and uses the samples as control poses. Throws DataError naming the source if it is too short.
  static SplineTrajectory from_recorded(const Trajectory& recorded, TimeNs dt);

  KinematicState at(TimeNs t) const override;
  TimeNs t_begin() const override { return t0_ + dt_; }
  TimeNs t_end() const override { return t0_ + static_cast<TimeNs>(q_.size() - 2) * dt_; }
  std::string describe() const override { return name_; }

 private:
  TimeNs t0_;
  TimeNs dt_;
  std::vector<Eigen::Quaterniond> q_;
  std::vector<Eigen::Vector3d> p_;
  std::vector<Eigen::Vector3d> omega_;  // Log(q_{k-1}^-1 q_k) for k >= 1
  std::string name_;
};

/// A recorded state trajectory (EuRoC state CSV: poses with velocities) played back as it is: at every recorded
/// timestamp the pose is exactly the recorded one (images rendered there match the ground truth to the bit);
/// between two records the position is the cubic Hermite interpolant of the recorded positions and velocities
/// (so velocity and acceleration exist and agree with the record), the orientation is the slerp of the recorded
/// ones (constant body rate over the interval, w_R = Log(q_kᵀ q_k+1)/dt, dw_R = 0). Used where the IMU is
/// recorded too (Simulation's recorded:DIR mode): nothing here is smoothed, so the images stay consistent with
/// that IMU as far as the record itself is. Poses without velocity get the central difference of the positions.
class RecordedTrajectory final : public ContinuousTrajectory {
 public:
  /// Needs at least 2 poses with increasing timestamps (DataError naming the source otherwise).
  explicit RecordedTrajectory(const Trajectory& recorded);
  KinematicState at(TimeNs t) const override;
  TimeNs t_begin() const override { return t_.front(); }
  TimeNs t_end() const override { return t_.back(); }
  std::string describe() const override { return name_; }

 private:
  std::vector<TimeNs> t_;
  std::vector<Eigen::Quaterniond> q_;
  std::vector<Eigen::Vector3d> p_, v_;
  std::string name_;
};

/// Low dynamics hand-held motion inside a room centred at `center` (m, W): slow sums of sinusoids with phases
/// drawn from `seed`, a few metres of path, the camera sweeping the walls; starts at rest (2 s warm-up).
std::unique_ptr<ContinuousTrajectory> make_handheld(std::uint64_t seed, const Eigen::Vector3d& center,
                                                    double duration_s, TimeNs t_begin = 0);

/// The RT-SLAM paper's high-dynamic profile: 1 s at rest, each of the 6 DoF excited in turn (x, y, z, roll, pitch,
/// yaw), then y and yaw together with extreme dynamics: yaw rate above 400 deg/s, angular acceleration above
/// 3000 deg/s², accelerations above 3 g. Phases are drawn from `seed`. Needs duration >= 40 s to reach the
/// extreme part (it starts at 26 s).
std::unique_ptr<ContinuousTrajectory> make_high_dynamic(std::uint64_t seed, const Eigen::Vector3d& center,
                                                        double duration_s, TimeNs t_begin = 0);

/// A wheeled ground robot driving laps of an ellipse at a constant height (the camera's, looking where it drives):
/// p = center + (a cos φ, b sin φ, 0), heading ψ = the direction of motion, R_WR = Rz(ψ) R_base (x up, z forward;
/// no pitch or roll), so the body rate is ψ̇ about R's x. φ(t) = φ0 ± ∫ φ̇ with φ̇ rising smoothly (smootherstep, C²)
/// from 0 to `rate` rad/s over [rest_s, rest_s + ramp_s]: at rest first, then the same lap over and over (faster
/// along the long sides: φ̇ is constant, not the speed). Exact first and second derivatives.
struct GroundTrajectoryParams {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double a = 2.0, b = 1.5;  // semi-axes along W's x and y (m)
  double rate = 0.25;       // φ̇ after the ramp (rad/s); the sign sets the direction of travel
  double phase = 0.0;       // φ at the start (rad)
  double rest_s = 1.0, ramp_s = 2.0;
  TimeNs t_begin = 0;
  double duration_s = 60.0;
  std::string name = "ground";
};

class GroundTrajectory final : public ContinuousTrajectory {
 public:
  explicit GroundTrajectory(GroundTrajectoryParams params);
  KinematicState at(TimeNs t) const override;
  TimeNs t_begin() const override { return params_.t_begin; }
  TimeNs t_end() const override { return params_.t_begin + from_seconds(params_.duration_s); }
  std::string describe() const override { return params_.name; }

 private:
  GroundTrajectoryParams params_;
};

/// The `ground` preset's motion: laps of an ellipse with semi-axes 0.3 × the room's footprint around `center`
/// (its height: the camera's, 0.5 m above the floor) at about `speed_mps` on average, starting point and direction
/// drawn from `seed`, 1 s at rest and a 2 s start.
std::unique_ptr<ContinuousTrajectory> make_ground(std::uint64_t seed, const Eigen::Vector3d& center,
                                                  const Eigen::Vector2d& room_size, double speed_mps,
                                                  double duration_s, TimeNs t_begin = 0);

/// A recorded trajectory (TUM text or EuRoC CSV, read by io::read_trajectory) smoothed by a cubic B-spline with
/// knot spacing `knot_dt_s`.
std::unique_ptr<ContinuousTrajectory> make_follow(const std::string& path, double knot_dt_s = 0.05);

}  // namespace rtslam::sim
