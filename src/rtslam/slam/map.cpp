#include "rtslam/slam/map.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/sensor.hpp"

namespace rtslam::slam {

Map::Map(filter::StateOptions options) : state_(options) {}
Map::~Map() = default;

Robot& Map::add_robot(std::unique_ptr<Robot> robot, const Eigen::VectorXd& mean, const Eigen::MatrixXd& cov,
                      TimeNs t0) {
  RTSLAM_CHECK(robot != nullptr, "null robot");
  robot->attach(*this, static_cast<int>(robots_.size()), mean, cov, t0);
  robots_.push_back(std::move(robot));
  // Landmarks that already exist get observations for the new sensors.
  for (auto& l : landmarks_) create_observations(*l);
  return *robots_.back();
}

std::vector<Sensor*> Map::sensors() const {
  std::vector<Sensor*> out;
  for (const auto& r : robots_)
    for (const auto& s : r->sensors()) out.push_back(s.get());
  return out;
}

void Map::create_observations(Landmark& lmk) {
  for (const auto& r : robots_) {
    for (const auto& s : r->sensors()) {
      if (!s->observes_landmarks() || lmk.observation_of(*s)) continue;
      Observation o;
      o.sensor = s.get();
      o.landmark = &lmk;
      lmk.observations_.push_back(std::move(o));
    }
  }
}

Landmark* Map::add_landmark(const filter::BlockLayout& layout, const Eigen::Ref<const Eigen::VectorXd>& mean,
                            std::span<const filter::BlockId> parents, const Eigen::Ref<const Eigen::MatrixXd>& J,
                            const Eigen::Ref<const Eigen::MatrixXd>& Q,
                            const std::function<std::unique_ptr<Landmark>(int id, filter::BlockId block)>& make) {
  const auto block = state_.add_block(layout, mean, parents, J, Q);
  if (!block) return nullptr;
  auto lmk = make(next_landmark_id_++, *block);
  lmk->ambient_offset_ = state_.block(*block).ambient_offset;
  lmk->first_estimate = mean;
  create_observations(*lmk);
  landmarks_.push_back(std::move(lmk));
  return landmarks_.back().get();
}

Landmark* Map::reparametrize(Landmark& old, const filter::BlockLayout& layout,
                             const Eigen::Ref<const Eigen::VectorXd>& mean,
                             const Eigen::Ref<const Eigen::MatrixXd>& J_new_old,
                             const std::function<std::unique_ptr<Landmark>(int id, filter::BlockId block)>& make) {
  const filter::BlockId parents[1] = {old.block()};
  const Eigen::MatrixXd Q = Eigen::MatrixXd::Zero(layout.tangent_size(), layout.tangent_size());
  const auto block = state_.add_block(layout, mean, parents, J_new_old, Q);
  if (!block) return nullptr;
  auto lmk = make(old.id(), *block);
  lmk->ambient_offset_ = state_.block(*block).ambient_offset;
  lmk->first_estimate = mean;
  lmk->descriptor = std::move(old.descriptor);
  lmk->frame_created = old.frame_created;
  lmk->sensor_created = old.sensor_created;
  lmk->observations_ = std::move(old.observations_);
  for (auto& o : lmk->observations_) o.landmark = lmk.get();
  state_.remove_block(old.block());
  auto it = std::find_if(landmarks_.begin(), landmarks_.end(), [&](const auto& p) { return p.get() == &old; });
  RTSLAM_CHECK(it != landmarks_.end(), "reparametrize: landmark not in this map");
  *it = std::move(lmk);
  return it->get();
}

void Map::remove_landmark(Landmark& lmk) {
  auto it = std::find_if(landmarks_.begin(), landmarks_.end(), [&](const auto& p) { return p.get() == &lmk; });
  RTSLAM_CHECK(it != landmarks_.end(), "remove_landmark: landmark not in this map");
  state_.remove_block(lmk.block());
  landmarks_.erase(it);
}

void Map::reserve_length_scaling() {
  const Eigen::Index n = state_.covariance().rows();
  if (length_factors_.size() != n) length_factors_.resize(n);
  const int k = state_.nullspace_dim();
  if (basis_change_.rows() != k) basis_change_.resize(k, k);
}

bool Map::scale_lengths(double c, const Eigen::Vector3d& centre) {
  RTSLAM_CHECK(c > 0.0 && std::isfinite(c), "Map::scale_lengths: the factor must be positive and finite");
  std::size_t unit_free = 0;  // the sensors' time offsets (s)
  for (const auto& r : robots_) {
    if (!r->can_scale_lengths()) return false;
    for (const auto& s : r->sensors()) {
      if (s->block() != filter::kNoBlock) return false;  // extrinsics
      if (s->time_block() != filter::kNoBlock) ++unit_free;
    }
  }
  if (state_.block_count() != static_cast<int>(robots_.size() + landmarks_.size() + unit_free)) return false;
  for (const auto& l : landmarks_)
    if (!l->can_scale_lengths()) return false;
  const bool basis = state_.nullspace_dim() == Robot::kNullspaceDim;
  if (state_.nullspace_dim() != 0 && !basis) return false;
  reserve_length_scaling();
  length_factors_.setOnes();
  if (basis) {
    // D N = [c N_t', N_φ' + N_t' (1 − c) [centre]×] with [N_t' N_φ'] the basis at the new means (positions
    // p' = centre + c (p − centre), so −[p']× = −c [p]× − (1 − c) [centre]×): N' = D N M with M below.
    basis_change_.setIdentity();
    basis_change_.topLeftCorner<3, 3>() = Eigen::Matrix3d::Identity() / c;
    basis_change_.topRightCorner<3, 3>() = -((1.0 - c) / c) * math::skew(centre);
  }
  const auto scale_block = [&](filter::BlockId b, auto& owner) {
    const filter::BlockInfo& info = state_.block(b);
    owner.scale_lengths(c, centre, state_.mean(b), length_factors_.segment(info.tangent_offset, info.tangent_size()));
  };
  for (const auto& r : robots_) scale_block(r->block(), *r);
  for (const auto& l : landmarks_) scale_block(l->block(), *l);
  if (basis)
    state_.scale_tangent(length_factors_, basis_change_);
  else
    state_.scale_tangent(length_factors_);
  for (const auto& r : robots_)
    for (const auto& s : r->sensors())
      if (DataManager* dm = s->data_manager()) dm->scale_lengths(*this, *s, c, centre);
  return true;
}

Landmark* Map::find_landmark(int id) const {
  for (const auto& l : landmarks_)
    if (l->id() == id) return l.get();
  return nullptr;
}

Map& World::add_map(filter::StateOptions options) {
  maps_.push_back(std::make_unique<Map>(options));
  return *maps_.back();
}

}  // namespace rtslam::slam
