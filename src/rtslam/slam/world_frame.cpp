#include "rtslam/slam/world_frame.hpp"

#include <vector>

#include "rtslam/slam/landmark.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/odometry_robot.hpp"
#include "rtslam/slam/robot.hpp"

namespace rtslam::slam {

namespace {

using Eigen::Matrix3d;
using Eigen::MatrixXd;
using Eigen::Vector3d;

// A block's part of the change: its Jacobian J (t × t) and its rows Γ (t × 6) of the change's uncertainty.
struct BlockChange {
  filter::BlockId id = filter::kNoBlock;
  MatrixXd J, Gamma;
};

// Rows of a point x (already in G) for [δc δφ] about c.
void point_rows(const Vector3d& x, const Vector3d& c, Eigen::Ref<MatrixXd> rows) {
  rows.leftCols<3>().setIdentity();
  rows.rightCols<3>() = -math::skew(x - c);
}

}  // namespace

std::string change_world_frame(Map& map, const WorldChange& change,
                               const std::function<void(Landmark&, const math::Pose& T_GW)>& on_landmark) {
  filter::State& state = map.state();
  const Matrix3d R = change.T_GW.q.toRotationMatrix();
  const Vector3d& t = change.T_GW.p;
  const Vector3d& c = change.center_G;
  for (const auto& r : map.robots()) {
    if (dynamic_cast<const ConstantVelocityRobot*>(r.get()) == nullptr &&
        dynamic_cast<const InertialRobot*>(r.get()) == nullptr &&
        dynamic_cast<const OdometryRobot*>(r.get()) == nullptr) {
      return "robot '" + r->name() + "' is of a type whose world-frame states are not known here";
    }
  }
  std::vector<BlockChange> changes;
  changes.reserve(static_cast<std::size_t>(state.block_count()));
  auto add = [&](filter::BlockId id) -> BlockChange& {
    BlockChange& b = changes.emplace_back();
    b.id = id;
    const int n = state.block(id).tangent_size();
    b.J = MatrixXd::Identity(n, n);
    b.Gamma = MatrixXd::Zero(n, 6);
    return b;
  };
  // Robots: [p q v ...] with the model's own vectors in W (the odometry robot: [p q] alone; its increments are in R).
  for (const auto& r : map.robots()) {
    auto x = state.mean(r->block());
    BlockChange& b = add(r->block());
    x.head<3>() = R * x.head<3>() + t;
    const Eigen::Quaterniond q = (change.T_GW.q * math::quat_from_wxyz(x.segment<4>(3))).normalized();
    x.segment<4>(3) = math::quat_to_wxyz(q);
    b.J.block<3, 3>(0, 0) = R;
    point_rows(x.head<3>(), c, b.Gamma.middleRows(0, 3));
    b.Gamma.block<3, 3>(3, 3) = q.toRotationMatrix().transpose();
    // Vectors in W: velocity (constant velocity and inertial) and gravity (inertial).
    std::vector<std::pair<int, int>> vectors;  // (ambient, tangent) offsets
    if (dynamic_cast<const OdometryRobot*>(r.get()) == nullptr) vectors.emplace_back(7, 6);
    if (dynamic_cast<const InertialRobot*>(r.get()) != nullptr) {
      using I = models::InertialIndex;
      vectors.emplace_back(I::kG, I::kDg);
    }
    for (const auto& [a, d] : vectors) {
      x.segment<3>(a) = R * x.segment<3>(a);
      b.J.block<3, 3>(d, d) = R;
      b.Gamma.block<3, 3>(d, 3) = -math::skew(x.segment<3>(a));
    }
    // The first estimate of FEJ was in W: the next prediction takes a new one.
    r->set_first_estimate_jacobians(r->first_estimate_jacobians());
  }
  for (const auto& l : map.landmarks()) {
    auto x = state.mean(l->block());
    BlockChange& b = add(l->block());
    if (l->type() == LandmarkType::AhpPoint) {  // [p0 m ρ]
      x.head<3>() = R * x.head<3>() + t;
      x.segment<3>(3) = R * x.segment<3>(3);
      b.J.block<3, 3>(0, 0) = R;
      b.J.block<3, 3>(3, 3) = R;
      point_rows(x.head<3>(), c, b.Gamma.middleRows(0, 3));
      b.Gamma.block<3, 3>(3, 3) = -math::skew(x.segment<3>(3));
      if (l->first_estimate.size() == 7) {
        l->first_estimate.head<3>() = R * l->first_estimate.head<3>() + t;
        l->first_estimate.segment<3>(3) = R * l->first_estimate.segment<3>(3);
      }
    } else {  // Euclidean [x]
      x.head<3>() = R * x.head<3>() + t;
      b.J.block<3, 3>(0, 0) = R;
      point_rows(x.head<3>(), c, b.Gamma.middleRows(0, 3));
      if (l->first_estimate.size() == 3) l->first_estimate = R * l->first_estimate + t;
    }
  }
  // Every other block (sensor extrinsics in R) keeps J = I, Γ = 0.
  std::vector<bool> seen;
  for (const BlockChange& b : changes) {
    if (static_cast<std::size_t>(b.id) >= seen.size()) seen.resize(static_cast<std::size_t>(b.id) + 1, false);
    seen[static_cast<std::size_t>(b.id)] = true;
  }
  int found = static_cast<int>(changes.size());
  for (filter::BlockId id = 0; found < state.block_count(); ++id) {
    if (!state.valid(id) || (static_cast<std::size_t>(id) < seen.size() && seen[static_cast<std::size_t>(id)])) continue;
    add(id);
    ++found;
  }
  // P_ab ← J_a P_ab J_bᵀ + Γ_a Σ Γ_bᵀ over every pair, mirrored.
  for (std::size_t i = 0; i < changes.size(); ++i) {
    const BlockChange& a = changes[i];
    const MatrixXd GS = a.Gamma * change.cov;
    for (std::size_t j = i; j < changes.size(); ++j) {
      const BlockChange& b = changes[j];
      const MatrixXd P_ab = a.J * state.cov(a.id, b.id) * b.J.transpose() + GS * b.Gamma.transpose();
      state.cov(a.id, b.id) = P_ab;
      if (j != i) state.cov(b.id, a.id) = P_ab.transpose();
      else state.cov(a.id, a.id) = 0.5 * (P_ab + P_ab.transpose());
    }
  }
  // The tracked basis of the world frame's directions (slam/consistency: oc) at the new means: robots give theirs,
  // points move as δx = t − [x]× φ, AHP directions as δm = −[m]× φ; sensor blocks (in R) have zero rows, unchanged.
  if (state.nullspace_dim() > 0) {
    for (const auto& r : map.robots()) {
      MatrixXd N(state.block(r->block()).tangent_size(), state.nullspace_dim());
      r->nullspace(state.mean(r->block()), N);
      state.set_nullspace(r->block(), N);
    }
    for (const auto& l : map.landmarks()) {
      const auto x = state.mean(l->block());
      MatrixXd N = MatrixXd::Zero(state.block(l->block()).tangent_size(), state.nullspace_dim());
      point_rows(x.head<3>(), Vector3d::Zero(), N.topRows(3));
      if (l->type() == LandmarkType::AhpPoint) N.block<3, 3>(3, 3) = -math::skew(x.segment<3>(3));
      state.set_nullspace(l->block(), N);
    }
  }
  if (on_landmark) {
    for (const auto& l : map.landmarks()) on_landmark(*l, change.T_GW);
  }
  return {};
}

}  // namespace rtslam::slam
