#pragma once
// A Map owns the estimation engine (filter::State) and the robots and landmarks whose states it holds; the
// World owns maps. Several robots, several sensors per robot, several landmark types, and landmarks shared by
// every sensor are possible: each new landmark gets one Observation per sensor of every robot in the map.
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "rtslam/filter/state.hpp"
#include "rtslam/slam/landmark.hpp"
#include "rtslam/slam/robot.hpp"
#include "rtslam/slam/sensor.hpp"

namespace rtslam::slam {

class Map {
 public:
  explicit Map(filter::StateOptions options = {});
  Map(const Map&) = delete;
  Map& operator=(const Map&) = delete;
  ~Map();

  filter::State& state() { return state_; }
  const filter::State& state() const { return state_; }

  /// Adds a robot with its prior (mean: robot ambient layout; cov: tangent). Throws if the state is full.
  Robot& add_robot(std::unique_ptr<Robot> robot, const Eigen::VectorXd& mean, const Eigen::MatrixXd& cov, TimeNs t0);
  const std::vector<std::unique_ptr<Robot>>& robots() const { return robots_; }
  /// Every sensor of every robot, in robot then sensor order.
  std::vector<Sensor*> sensors() const;

  /// Adds a landmark block built from parents (see filter::State::add_block) and a landmark object made by
  /// `make(id, block)`. Returns nullptr if the state has no room.
  Landmark* add_landmark(const filter::BlockLayout& layout, const Eigen::Ref<const Eigen::VectorXd>& mean,
                         std::span<const filter::BlockId> parents, const Eigen::Ref<const Eigen::MatrixXd>& J,
                         const Eigen::Ref<const Eigen::MatrixXd>& Q,
                         const std::function<std::unique_ptr<Landmark>(int id, filter::BlockId block)>& make);
  /// Replaces a landmark by another parametrization x_new = g(x_old) with Jacobian J_new_old (e.g. AHP →
  /// Euclidean); id, descriptor and observations (counters) carry over, the old block is freed.
  /// Returns the new landmark, or nullptr (nothing changed) if there is no room.
  Landmark* reparametrize(Landmark& old, const filter::BlockLayout& layout, const Eigen::Ref<const Eigen::VectorXd>& mean,
                          const Eigen::Ref<const Eigen::MatrixXd>& J_new_old,
                          const std::function<std::unique_ptr<Landmark>(int id, filter::BlockId block)>& make);
  void remove_landmark(Landmark& lmk);
  const std::vector<std::unique_ptr<Landmark>>& landmarks() const { return landmarks_; }
  Landmark* find_landmark(int id) const;
  /// Landmarks added since the map was made, removed ones included (ids are 0 .. landmarks_added() - 1).
  int landmarks_added() const { return next_landmark_id_; }
  /// Changes the map's unit of length about the point `centre` (W): every position of the state (robots, landmarks,
  /// anchors) moves to centre + c (p − centre), c > 0, inverse distances are divided by c, directions, attitudes
  /// and unit-free states keep their values, and the covariance and the unobservable basis are transformed alike
  /// (P ← D P D; the tracked unobservable basis [t φ] re-expressed at the new means). A camera at its robot's origin
  /// sees every landmark in the same direction after it (one mounted away from it keeps its metric lever arm: nearly
  /// so). The sensors' data managers are told (DataManager::scale_lengths: the views of the landmarks' patches).
  /// False, and nothing changed, when a robot or landmark cannot (Robot::can_scale_lengths), the state holds other
  /// blocks than theirs and the sensors' time offsets (a sensor's extrinsics are metric), or its basis is not
  /// [t φ]. No allocation after reserve_length_scaling().
  bool scale_lengths(double c, const Eigen::Vector3d& centre = Eigen::Vector3d::Zero());
  /// Sizes scale_lengths' workspace (at a run's start, so that a rescale does not allocate).
  void reserve_length_scaling();
  /// A new sensor (or input stream) id, unique in this map.
  int take_sensor_id() { return next_sensor_id_++; }

 private:
  void create_observations(Landmark& lmk);
  filter::State state_;
  std::vector<std::unique_ptr<Robot>> robots_;
  std::vector<std::unique_ptr<Landmark>> landmarks_;
  int next_landmark_id_ = 0;
  int next_sensor_id_ = 0;
  Eigen::VectorXd length_factors_;  // scale_lengths' workspace (tangent capacity)
  Eigen::MatrixXd basis_change_;    // and the unobservable basis's change of columns
  friend class Robot;
};

class World {
 public:
  Map& add_map(filter::StateOptions options = {});
  const std::vector<std::unique_ptr<Map>>& maps() const { return maps_; }

 private:
  std::vector<std::unique_ptr<Map>> maps_;
};

}  // namespace rtslam::slam
