#include "rtslam/strategies/known_association.hpp"

#include <algorithm>
#include <any>
#include <chrono>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/slam/landmark_init.hpp"
#include "rtslam/slam/observation.hpp"

namespace rtslam::strategies {

void KnownAssociationOptions::validate() const {
  const std::string w = "association";
  require_bound(sigma_px > 0.0 && sigma_px <= 100.0, w, "sigma_px", sigma_px, "in (0, 100] px");
  require_bound(n_sigma > 0.0 && n_sigma <= 10.0, w, "n_sigma", n_sigma, "in (0, 10]");
  require_bound(max_updates >= 0 && max_updates <= 10000, w, "max_updates", max_updates, "in [0, 10000]");
  require_bound(max_inits >= 0 && max_inits <= 1000, w, "max_inits", max_inits, "in [0, 1000]");
  require_bound(gain_recomputations >= 1 && gain_recomputations <= 100, w, "gain_recomputations", gain_recomputations,
                "in [1, 100]");
  require_bound(margin_px >= 0.0 && margin_px <= 1000.0, w, "margin_px", margin_px, "in [0, 1000] px");
  grid.validate(w + "/grid");
  prior.validate(w);
}

KnownAssociationDataManager::KnownAssociationDataManager(KnownAssociationOptions options,
                                                         const slam::MapManager& map_manager, int width, int height,
                                                         std::uint64_t seed)
    : opt_((options.validate(), options)),
      map_manager_(map_manager),
      grid_(width, height, opt_.grid),
      rng_(seed),
      corrector_(std::max(1, (opt_.max_updates + opt_.gain_recomputations - 1) / opt_.gain_recomputations)) {
  candidates_.reserve(512);
  batch_.reserve(static_cast<size_t>(corrector_.max_observations()));
}

namespace {
int point_id_of(const slam::Landmark& l) { return std::any_cast<int>(l.descriptor); }
}  // namespace

void KnownAssociationDataManager::process(slam::Map& map, slam::Sensor& sensor, const slam::RawData& raw, long frame,
                                          slam::FrameStats& stats) {
  using Clock = std::chrono::steady_clock;
  const auto* points = dynamic_cast<const RawPoints*>(&raw);
  if (!points) throw ConfigError("known-association data manager: raw data is not a point list");
  const auto t0 = Clock::now();
  filter::State& state = map.state();

  // Index the measurements by point id (storage grows to the largest id once, then is reused).
  int max_id = -1;
  for (const auto& m : points->points) max_id = std::max(max_id, m.point_id);
  for (const auto& l : map.landmarks()) max_id = std::max(max_id, point_id_of(*l));
  if (static_cast<int>(measurement_of_point_.size()) <= max_id) {
    measurement_of_point_.resize(static_cast<size_t>(max_id) + 1);
    point_in_map_.resize(static_cast<size_t>(max_id) + 1);
  }
  std::fill(measurement_of_point_.begin(), measurement_of_point_.end(), -1);
  std::fill(point_in_map_.begin(), point_in_map_.end(), 0);
  for (size_t i = 0; i < points->points.size(); ++i) {
    measurement_of_point_[static_cast<size_t>(points->points[i].point_id)] = static_cast<int>(i);
  }

  // 1. Predict all observations of this sensor; keep the visible ones.
  grid_.reset(rng_);
  candidates_.clear();
  for (const auto& l : map.landmarks()) {
    point_in_map_[static_cast<size_t>(point_id_of(*l))] = 1;
    slam::Observation* o = l->observation_of(sensor);
    if (!slam::predict_observation(state, state.mean_vector(), *o, opt_.margin_px, true)) continue;
    slam::compute_innovation_covariance(state, *o, opt_.sigma_px);
    o->counters.last_visible_frame = frame;
    grid_.occupy(o->h);
    candidates_.push_back(o);
  }
  stats.visible = static_cast<int>(candidates_.size());
  // 2. Active search, most informative (largest ellipse) first.
  std::sort(candidates_.begin(), candidates_.end(), [](const slam::Observation* a, const slam::Observation* b) {
    return a->S.determinant() > b->S.determinant();
  });
  const auto t1 = Clock::now();
  const double gate = opt_.n_sigma * opt_.n_sigma;
  const int per_round = (opt_.max_updates + opt_.gain_recomputations - 1) / opt_.gain_recomputations;
  size_t next = 0;
  for (int round = 0; round < opt_.gain_recomputations && next < candidates_.size(); ++round) {
    batch_.clear();
    const int budget = std::min(per_round, opt_.max_updates - stats.updated);
    while (next < candidates_.size() && static_cast<int>(batch_.size()) < budget) {
      slam::Observation* o = candidates_[next++];
      ++o->counters.searched;
      ++stats.searched;
      const int mi = measurement_of_point_[static_cast<size_t>(point_id_of(*o->landmark))];
      if (mi < 0) {
        ++o->counters.failed;
        continue;
      }
      ++o->counters.matched;
      ++stats.matched;
      // Re-predict at the current estimate (earlier rounds of this frame moved it) and gate individually.
      if (!slam::predict_observation(state, state.mean_vector(), *o, 0.0, true)) {
        ++o->counters.failed;
        continue;
      }
      slam::compute_innovation_covariance(state, *o, opt_.sigma_px);
      o->z = points->points[static_cast<size_t>(mi)].z;
      o->y = o->z - o->h;
      o->mahalanobis2 = o->y.dot(o->S.ldlt().solve(o->y));
      if (!(o->mahalanobis2 <= gate)) {
        ++o->counters.failed;
        continue;
      }
      batch_.push_back(o);
    }
    if (batch_.empty()) continue;
    slam::BatchCorrectionOptions bo;
    bo.sigma_px = opt_.sigma_px;
    const auto res = corrector_.correct(state, batch_, bo);
    for (slam::Observation* o : batch_) {
      if (res.ok()) {
        ++o->counters.updated;
        o->counters.last_updated_frame = frame;
        ++stats.updated;
      } else {
        ++o->counters.failed;
      }
    }
  }
  const auto t2 = Clock::now();

  // 3. Initialization in empty cells of the moving grid.
  int inits = 0;
  for (int cell : grid_.empty_cells(rng_)) {
    if (inits >= opt_.max_inits || !map_manager_.has_room(map, 7)) break;
    const Eigen::Vector4d r = grid_.cell_rect(cell);
    const Eigen::Vector2d centre(0.5 * (r[0] + r[2]), 0.5 * (r[1] + r[3]));
    int best = -1;
    double best_d2 = 0.0;
    for (size_t i = 0; i < points->points.size(); ++i) {
      const auto& m = points->points[i];
      if (point_in_map_[static_cast<size_t>(m.point_id)]) continue;
      if (m.z.x() < r[0] || m.z.x() >= r[2] || m.z.y() < r[1] || m.z.y() >= r[3]) continue;
      const double d2 = (m.z - centre).squaredNorm();
      if (best < 0 || d2 < best_d2) {
        best = static_cast<int>(i);
        best_d2 = d2;
      }
    }
    if (best < 0) continue;
    const auto& m = points->points[static_cast<size_t>(best)];
    slam::Landmark* l = slam::init_ahp_landmark(map, sensor, m.z, opt_.sigma_px, opt_.prior, frame);
    if (!l) break;
    l->descriptor = m.point_id;
    point_in_map_[static_cast<size_t>(m.point_id)] = 1;
    ++inits;
  }
  stats.initialized = inits;
  const auto t3 = Clock::now();
  stats.time_predict_ms += std::chrono::duration<double, std::milli>(t1 - t0).count();
  stats.time_update_ms = std::chrono::duration<double, std::milli>(t2 - t1).count();
  stats.time_init_ms = std::chrono::duration<double, std::milli>(t3 - t2).count();
}

}  // namespace rtslam::strategies
