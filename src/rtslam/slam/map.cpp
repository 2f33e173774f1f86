#include "rtslam/slam/map.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/slam/managers.hpp"

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

bool Map::scale_lengths(double c, const Eigen::Vector3d& centre) {
  RTSLAM_CHECK(c > 0.0 && std::isfinite(c), "Map::scale_lengths: the factor must be positive and finite");
  if (state_.block_count() != static_cast<int>(robots_.size() + landmarks_.size())) return false;
  for (const auto& r : robots_)
    if (!r->can_scale_lengths()) return false;
  for (const auto& l : landmarks_)
    if (!l->can_scale_lengths()) return false;
  length_factors_.setOnes(state_.covariance().rows());
  const auto scale_block = [&](filter::BlockId b, auto& owner) {
    const filter::BlockInfo& info = state_.block(b);
    owner.scale_lengths(c, centre, state_.mean(b), length_factors_.segment(info.tangent_offset, info.tangent_size()));
  };
  for (const auto& r : robots_) scale_block(r->block(), *r);
  for (const auto& l : landmarks_) scale_block(l->block(), *l);
  state_.scale_tangent(length_factors_);
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
