#pragma once
// Robots: a state block in the map whose first segments are the pose [p_WR(3) q_WR(4)] (tangent [δp δθ], the
// first 6 covariance rows of the block), then model-specific states. Robots own their sensors.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rtslam/core/ring_buffer.hpp"
#include "rtslam/core/time.hpp"
#include "rtslam/filter/state.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/models/robots/constant_velocity.hpp"
#include "rtslam/models/robots/inertial.hpp"
#include "rtslam/slam/fwd.hpp"
#include "rtslam/slam/managers.hpp"

namespace rtslam::slam {

/// One IMU sample (IMU clock): a proprioceptive input of the robot whose input id is sensor_id (System::add_robot).
struct ImuData final : RawData {
  models::ImuMeasurement m;
};

class Robot {
 public:
  virtual ~Robot();
  Robot(const Robot&) = delete;
  Robot& operator=(const Robot&) = delete;

  int id() const { return id_; }
  const std::string& name() const { return name_; }
  filter::BlockId block() const { return block_; }
  Map& map() const { return *map_; }
  bool in_map() const { return map_ != nullptr; }
  TimeNs time() const { return time_; }

  /// T_WR from a mean vector (the map's, or a hypothesis of one-point RANSAC).
  math::Pose pose(const Eigen::VectorXd& mean) const;
  math::Pose pose() const;
  /// Moves the robot (mean and covariance) to time t. Returns false if t is before the robot's time.
  virtual bool predict_to(TimeNs t) = 0;
  /// Robots driven by proprioceptive inputs (IMU samples) can be predicted only up to their last input: the
  /// System holds exteroceptive data until the inputs cover them.
  virtual bool needs_inputs() const { return false; }
  /// One proprioceptive input (System::feed routes them); DataError for a robot that takes none.
  virtual void add_input(const RawData& input);
  /// A restart's state: the start's state x0 (in the starter's own frame) moved to where the robot last was
  /// healthy (`last_good`, the robot's block mean then), so that a restart keeps the world frame. The base keeps
  /// x0's model states and takes the pose of last_good.
  virtual Eigen::VectorXd reanchor(const Eigen::VectorXd& x0, const Eigen::VectorXd& last_good,
                                   const HealthOptions& health) const;
  virtual filter::BlockLayout layout() const = 0;
  /// The block's rows (tangent × 6) of the directions no exteroceptive measurement can observe, at the block mean
  /// x: a global translation t and rotation φ of the world, [t φ] (filter observability constraints). For a pose
  /// [p q ...] in W: δp = t − [p]× φ, δθ = R_WRᵀ φ; vectors v in W rotate (δv = −[v]× φ); body-frame states do
  /// not move. Constrained predictions adjust only the transition's attitude-error columns (tangent 3..5), where
  /// the linearization point enters.
  virtual void nullspace(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::MatrixXd> N) const = 0;
  static constexpr int kNullspaceDim = 6;
  /// The pose's rate of change at the robot's time for the block mean in `mean`, in the pose's tangent
  /// [δp (W) δθ (R, right perturbation)]: xi = [v_WR; ω_R], so that T_WR(t + s) ≈ T_WR ⊞ s·xi. The sensors' time
  /// offsets (Sensor::estimate_time_offset) move their pose along it. False for a robot that cannot tell it.
  virtual bool pose_rate(const Eigen::VectorXd& /*mean*/, Eigen::Matrix<double, 6, 1>& /*xi*/) const { return false; }
  /// At rest until the next prediction (the zero-velocity detector's verdict of the latest frame): a robot that can
  /// holds its state over the next prediction instead of integrating its inputs (OpenVINS's zero-velocity update
  /// does the same), the inputs' noise integrated over a standstill being all drift. Robots without inputs ignore it.
  virtual void set_at_rest(bool /*at_rest*/) {}
  /// The rate states a zero-velocity update sets to 0 (strategies/zero_velocity.hpp): how many tangent rows, from
  /// row 6 (ambient 7), right after the pose [p q]. 0 for a robot without such states (its state has no velocity:
  /// zero_velocity refuses it).
  virtual int rest_rows() const { return 0; }
  /// A change of the map's unit of length (Map::scale_lengths): whether every length in the robot's state can be
  /// multiplied by a factor (a robot with metric states, e.g. gravity, cannot: false by default).
  virtual bool can_scale_lengths() const { return false; }
  /// Scales the lengths in `mean` (the block's ambient mean) by c about `centre` (positions p → centre + c (p −
  /// centre), other lengths × c) and writes each tangent row's factor into d (1 for attitudes and unit-free states).
  /// Only for a robot that can_scale_lengths().
  virtual void scale_lengths(double c, const Eigen::Vector3d& centre, Eigen::Ref<Eigen::VectorXd> mean,
                             Eigen::Ref<Eigen::VectorXd> d);

  Sensor& add_sensor(std::unique_ptr<Sensor> sensor);
  /// Gives the sensors without an id one from the map's counter (System::add_robot: data name their sensor before
  /// the robot is in the map).
  void assign_sensor_ids(Map& map);
  const std::vector<std::unique_ptr<Sensor>>& sensors() const { return sensors_; }

  /// Called by Map::add_robot: allocates the block with the given prior (gauge: the first robot's pose defines
  /// the world frame, so its pose rows may have zero covariance).
  void attach(Map& map, int id, const Eigen::VectorXd& mean, const Eigen::MatrixXd& cov, TimeNs t0);
  /// Re-initializes the robot in its map at time t (not before its current time): its block is freed and allocated
  /// again with this prior (no cross-covariance with what remains of the map). The health monitor's recovery: the
  /// caller removes the landmarks first. Sensors and buffered data (IMU samples) are kept.
  void reset(const Eigen::VectorXd& mean, const Eigen::MatrixXd& cov, TimeNs t);

  /// First-estimate Jacobians (FEJ: Huang, Mourikis, Roumeliotis 2008): the transition of a prediction from t_k is
  /// evaluated along the states predicted from the robot's FIRST estimate at t_k (its prediction to t_k, before
  /// the corrections at t_k), not from the corrected mean; the mean itself still starts from the corrected one.
  void set_first_estimate_jacobians(bool on) { fej_ = on; fej_valid_ = false; }
  bool first_estimate_jacobians() const { return fej_; }

 protected:
  bool fej_ = false;
  bool fej_valid_ = false;  // fej_x_ holds the first estimate at time_
  /// After reset(): the robot's own bookkeeping of the map it was in (its landmarks are gone).
  virtual void restarted() {}
  explicit Robot(std::string name) : name_(std::move(name)) {}
  Map* map_ = nullptr;
  filter::BlockId block_ = filter::kNoBlock;
  TimeNs time_ = 0;

 private:
  void allocate_block(const Eigen::VectorXd& mean, const Eigen::MatrixXd& cov);
  int id_ = -1;
  std::string name_;
  std::vector<std::unique_ptr<Sensor>> sensors_;
};

/// The constant-velocity robot [p q v ω] (../shared/MATH.md "Robots"): prediction by dt with process noise
/// from continuous-time densities.
class ConstantVelocityRobot final : public Robot {
 public:
  explicit ConstantVelocityRobot(models::ConstantVelocityParams params, std::string name = "robot");
  bool predict_to(TimeNs t) override;
  filter::BlockLayout layout() const override { return static_layout(); }
  /// [p q v ω]: p and v in W move with the world, ω (robot frame) does not.
  void nullspace(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::MatrixXd> N) const override;
  static filter::BlockLayout static_layout();
  /// [v; ω] of the state.
  bool pose_rate(const Eigen::VectorXd& mean, Eigen::Matrix<double, 6, 1>& xi) const override;
  /// v and ω.
  int rest_rows() const override { return 6; }
  const models::ConstantVelocityParams& params() const { return params_; }

 private:
  models::ConstantVelocityParams params_;
  models::Vector13d x_tmp_;
  models::Vector13d fej_x_, fej_tmp_;
  models::Matrix12d F_;
  models::Matrix12d Q_;
  Eigen::Matrix<double, 12, 6> N_;
};

/// The inertial robot [p q v a_b ω_b g] (../shared/MATH.md "Robots", models/robots/inertial.hpp): IMU samples drive
/// the prediction. Samples are buffered by add_imu (IMU clock, strictly increasing); predict_to(t) integrates them
/// with the midpoint rule up to t, interpolating the reading at t inside the last interval, and applies the
/// composed transition Φ = Π F_k and noise Q = Σ Φ_k Q_k Φ_kᵀ of the whole interval in one covariance update (the
/// cross-covariances with the map are touched once per image, not per sample).
class InertialRobot final : public Robot {
 public:
  explicit InertialRobot(models::InertialParams params, std::string name = "robot");
  /// Buffers one IMU sample; DataError if it is not after the previous one.
  void add_imu(TimeNs t, const models::ImuMeasurement& m);
  /// Time of the latest buffered sample (the robot can be predicted up to it); nullopt before the first.
  std::optional<TimeNs> imu_coverage() const;
  /// Integrates to t; DataError if the IMU does not cover t. False if t is before the robot's time.
  bool predict_to(TimeNs t) override;
  bool needs_inputs() const override { return true; }
  /// An ImuData sample (add_imu).
  void add_input(const RawData& input) override;
  /// Position of last_good; attitude, velocity and gravity of x0 turned about the vertical so that the heading of
  /// the body axis most orthogonal to gravity is last_good's; biases of last_good when plausible (half the
  /// health monitor's bounds), else x0's.
  Eigen::VectorXd reanchor(const Eigen::VectorXd& x0, const Eigen::VectorXd& last_good,
                           const HealthOptions& health) const override;
  filter::BlockLayout layout() const override { return static_layout(); }
  /// v (the biases and gravity are not rates).
  int rest_rows() const override { return 3; }
  /// [p q v a_b ω_b g]: p, v and the gravity vector g (all in W) move with the world; the biases do not. With g a
  /// state, every rotation of the world is unobservable, not only the yaw.
  void nullspace(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::MatrixXd> N) const override;
  static filter::BlockLayout static_layout();
  /// [v; ω̄_m − ω_b]: v and the gyro bias of the state, ω̄_m the mean gyro reading over the last prediction
  /// interval (at least 10 ms; the rotation increment over dt, free of the vibration of single readings); before
  /// the first such interval, the reading at the robot's time interpolated between the buffered samples around it.
  /// False before any sample.
  bool pose_rate(const Eigen::VectorXd& mean, Eigen::Matrix<double, 6, 1>& xi) const override;
  const models::InertialParams& params() const { return params_; }
  long samples_integrated() const { return steps_; }
  /// While at rest, predict_to keeps p, q, v and g and lets only the biases random-walk (their noise added), unless
  /// the samples of the interval themselves show motion (a gyro or accelerometer reading off the state's bias- and
  /// gravity-corrected rest by more than kRestGyro / kRestAccel): then it integrates as usual.
  void set_at_rest(bool at_rest) override { at_rest_ = at_rest; }
  long samples_held() const { return held_; }
  static constexpr double kRestGyro = 0.3;   // rad/s
  static constexpr double kRestAccel = 4.0;  // m/s²

 private:
  /// A restart forgets a rest verdict given before it.
  void restarted() override { at_rest_ = false; }
  struct Sample {
    TimeNs t;
    models::ImuMeasurement m;
  };
  static models::ImuMeasurement lerp(const Sample& a, const Sample& b, TimeNs t);
  models::InertialParams params_;
  std::optional<Sample> prev_;  // the latest sample at or before time_
  RingBuffer<Sample> pending_{64};  // samples after time_ (reused: no allocation per sample)
  long steps_ = 0;
  models::Vector19d x_;
  models::Vector19d fej_x_, fej_next_;
  models::Matrix18d F_, Q_, Phi_, Qacc_, tmp_;
  Eigen::Matrix<double, 18, 6> N_;
  // The mean gyro reading over the last prediction interval(s) spanning at least 10 ms (pose_rate).
  Eigen::Vector3d gyro_sum_ = Eigen::Vector3d::Zero(), gyro_mean_ = Eigen::Vector3d::Zero();
  TimeNs gyro_span_ = 0;
  bool gyro_mean_valid_ = false;
  bool at_rest_ = false;
  long held_ = 0;
  bool interval_at_rest(TimeNs t) const;
};

}  // namespace rtslam::slam
