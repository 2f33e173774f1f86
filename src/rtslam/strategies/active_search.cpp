#include "rtslam/strategies/active_search.hpp"

#include <algorithm>
#include <any>
#include <chrono>
#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/slam/batch_correction.hpp"
#include "rtslam/slam/landmark_init.hpp"
#include "rtslam/slam/observation.hpp"
#include "rtslam/slam/sensor.hpp"
#include "rtslam/vision/warp.hpp"

namespace rtslam::strategies {

const PointDescriptor* point_descriptor(const slam::Landmark& lmk) {
  const auto* p = std::any_cast<PointDescriptorPtr>(&lmk.descriptor);
  return p ? p->get() : nullptr;
}

void ActiveSearchDataManager::scale_lengths(slam::Map& map, const slam::Sensor& sensor, double c,
                                            const Eigen::Vector3d& centre) {
  for (const auto& l : map.landmarks()) {
    if (l->sensor_created != sensor.id()) continue;
    auto* held = std::any_cast<PointDescriptorPtr>(&l->descriptor);
    if (held == nullptr || *held == nullptr) continue;
    if (held->use_count() == 1) {
      // The only holder: changed in place (made non-const by make_shared), no allocation.
      auto& d = const_cast<PointDescriptor&>(**held);
      d.T_WS0.p = centre + c * (d.T_WS0.p - centre);
    } else {
      auto moved = std::make_shared<PointDescriptor>(**held);
      moved->T_WS0.p = centre + c * (moved->T_WS0.p - centre);
      *held = std::move(moved);
    }
  }
}

bool ransac_may_stop(int hypotheses, int best_support, int candidates, double confidence) {
  if (!(confidence > 0.0) || candidates <= 0 || best_support < 2 || hypotheses <= 0) return false;
  const double outlier = 1.0 - std::min(1.0, static_cast<double>(best_support) / candidates);
  // (1 − ε)^k ≤ 1 − confidence: that every hypothesis so far came from an outlier is at most that likely.
  return std::pow(outlier, hypotheses) <= 1.0 - confidence;
}

void ActiveSearchOptions::validate(const std::string& where) const {
  require_bound(sigma_px > 0.0 && sigma_px <= 100.0, where, "sigma_px", sigma_px, "in (0, 100] px");
  require_bound(n_sigma > 0.0 && n_sigma <= 10.0, where, "n_sigma", n_sigma, "in (0, 10]");
  require_bound(max_updates >= 0 && max_updates <= 32 * gain_recomputations, where, "max_updates", max_updates,
                "in [0, 32 * gain_recomputations]");
  require_bound(max_updates_ransac >= 0 && max_updates_ransac <= 32 && max_updates_ransac <= max_updates, where,
                "max_updates_ransac", max_updates_ransac, "in [0, min(32, max_updates)]");
  require_bound(ransac_ntries >= 0 && ransac_ntries <= 1000, where, "ransac_ntries", ransac_ntries, "in [0, 1000]");
  require_bound(ransac_confidence >= 0.0 && ransac_confidence < 1.0, where, "ransac_confidence", ransac_confidence,
                "0 (off) or in (0, 1)");
  require_bound(ransac_low_innov_px >= 0.0 && ransac_low_innov_px <= 100.0, where, "ransac_low_innov_px",
                ransac_low_innov_px, "in [0, 100] px");
  require_bound(gain_recomputations >= 1 && gain_recomputations <= 100, where, "gain_recomputations",
                gain_recomputations, "in [1, 100]");
  require_bound(iterations >= 1 && iterations <= 20, where, "iterations", iterations, "in [1, 20]");
  require_bound(iteration_tolerance > 0.0 && iteration_tolerance < 1.0, where, "iteration_tolerance",
                iteration_tolerance, "in (0, 1)");
  require_bound(max_inits >= 0 && max_inits <= 1000, where, "max_inits", max_inits, "in [0, 1000]");
  require_bound(max_search_size_px2 > 0.0 && max_search_size_px2 <= 1e8, where, "max_search_size_px2",
                max_search_size_px2, "in (0, 1e8] px²");
  require_bound(min_candidates >= 0 && min_candidates <= 1000, where, "min_candidates", min_candidates, "in [0, 1000]");
  require_bound(margin_px >= 0.0 && margin_px <= 1000.0, where, "margin_px", margin_px, "in [0, 1000] px");
  require_bound(init_patch_size >= zncc.patch_size && init_patch_size % 2 == 1 && init_patch_size <= 101, where,
                "init_patch_size", init_patch_size, "odd, >= zncc.patch_size and <= 101");
  grid.validate(where + "/grid");
  prior.validate(where);
  if (depth_prior != "fixed" && depth_prior != "scene") {
    throw ConfigError(fmt::format("{}: depth_prior = '{}' must be fixed or scene", where, depth_prior));
  }
  require_bound(time_budget_ms >= 0.0 && time_budget_ms <= kMaxTimeBudgetMs, where, "time_budget_ms", time_budget_ms,
                fmt::format("0 (off) or in (0, {:g}] ms", kMaxTimeBudgetMs));
  require_bound(scene_prior_min_points >= 1 && scene_prior_min_points <= 1000, where, "scene_prior_min_points",
                scene_prior_min_points, "in [1, 1000]");
  harris.validate(where + "/harris");
  zncc.validate(where + "/zncc");
}

ActiveSearchOptions ActiveSearchOptions::from_yaml(YamlMap& map) {
  ActiveSearchOptions o;
  map.get("sigma_px", o.sigma_px);
  map.get("second_order_depth", o.second_order_depth);
  map.get("n_sigma", o.n_sigma);
  map.get("max_updates", o.max_updates);
  map.get("max_updates_ransac", o.max_updates_ransac);
  map.get("ransac_ntries", o.ransac_ntries);
  map.get("ransac_confidence", o.ransac_confidence);
  map.get("ransac_low_innov_px", o.ransac_low_innov_px);
  map.get("gain_recomputations", o.gain_recomputations);
  map.get("iterations", o.iterations);
  map.get("iteration_tolerance", o.iteration_tolerance);
  map.get("max_inits", o.max_inits);
  map.get("max_search_size_px2", o.max_search_size_px2);
  map.get("min_candidates", o.min_candidates);
  map.get("margin_px", o.margin_px);
  map.get("init_patch_size", o.init_patch_size);
  map.get("d_min", o.prior.d_min);
  map.get("depth_prior", o.depth_prior);
  map.get("depth_prior_sigma_ratio", o.prior.sigma_ratio);
  map.get("scene_prior_min_points", o.scene_prior_min_points);
  map.get("time_budget_ms", o.time_budget_ms);
  {
    YamlMap g = map.child("grid");
    g.get("cells_x", o.grid.cells_x);
    g.get("cells_y", o.grid.cells_y);
    g.get("margin_px", o.grid.margin_px);
    g.finish();
  }
  if (map.has("harris")) {
    YamlMap h = map.child("harris");
    o.harris = vision::HarrisOptions::from_yaml(h);
  }
  if (map.has("zncc")) {
    YamlMap z = map.child("zncc");
    o.zncc = vision::ZnccOptions::from_yaml(z);
  }
  map.finish();
  o.validate(map.where());
  return o;
}

YAML::Node ActiveSearchOptions::to_yaml() const {
  YAML::Node s;
  s["sigma_px"] = sigma_px;
  s["second_order_depth"] = second_order_depth;
  s["n_sigma"] = n_sigma;
  s["max_updates"] = max_updates;
  s["max_updates_ransac"] = max_updates_ransac;
  s["ransac_ntries"] = ransac_ntries;
  s["ransac_confidence"] = ransac_confidence;
  s["ransac_low_innov_px"] = ransac_low_innov_px;
  s["gain_recomputations"] = gain_recomputations;
  s["iterations"] = iterations;
  s["iteration_tolerance"] = iteration_tolerance;
  s["max_inits"] = max_inits;
  s["max_search_size_px2"] = max_search_size_px2;
  s["min_candidates"] = min_candidates;
  s["margin_px"] = margin_px;
  s["init_patch_size"] = init_patch_size;
  s["d_min"] = prior.d_min;
  s["depth_prior"] = depth_prior;
  s["depth_prior_sigma_ratio"] = prior.sigma_ratio;
  s["scene_prior_min_points"] = scene_prior_min_points;
  s["time_budget_ms"] = time_budget_ms;
  s["grid"]["cells_x"] = grid.cells_x;
  s["grid"]["cells_y"] = grid.cells_y;
  s["grid"]["margin_px"] = grid.margin_px;
  s["harris"] = harris.to_yaml();
  s["zncc"] = zncc.to_yaml();
  return s;
}

namespace {
vision::ZnccOptions exhaustive(vision::ZnccOptions o) {
  o.two_level = false;
  return o;
}

class SteadyBudgetClock final : public BudgetClock {
 public:
  double now_ms() override {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
  }
};
SteadyBudgetClock g_steady_budget_clock;  // stateless: shared by every manager
}  // namespace

void ActiveSearchDataManager::set_budget_clock(BudgetClock* clock) {
  clock_ = clock != nullptr ? clock : &g_steady_budget_clock;
}

bool ActiveSearchDataManager::may_search() {
  if (opt_.time_budget_ms <= 0.0) return true;
  if (budget_spent_) return false;
  budget_spent_ = clock_->now_ms() - budget_start_ms_ >= opt_.time_budget_ms;
  return !budget_spent_;
}

ActiveSearchDataManager::ActiveSearchDataManager(ActiveSearchOptions options, const slam::MapManager& map_manager,
                                                 int width, int height, std::uint64_t seed)
    : opt_((options.validate(), options)),
      map_manager_(map_manager),
      grid_(width, height, opt_.grid),
      rng_(seed),
      matcher_(opt_.zncc),
      matcher_small_(exhaustive(opt_.zncc)),
      harris_(opt_.harris) {
  set_budget_clock(nullptr);
  candidates_.reserve(512);
  order_.reserve(512);
  oversized_.reserve(512);
  untried_.reserve(512);
  support_.reserve(512);
  best_support_.reserve(512);
  support_z_.reserve(512);
  best_support_z_.reserve(512);
  report_.reserve(512);
  depths_.reserve(512);
  batch_.reserve(kMaxBatch);
  batch_obs_.reserve(kMaxBatch);
  // The predicted patches of as many candidates as reserved above, sized now so that frames do not allocate.
  warp_buf_.resize(candidates_.capacity());
  patches_.resize(candidates_.capacity());
  memos_.resize(candidates_.capacity());
  for (vision::ScoreMemo& m : memos_) m.reserve(kMemoEntries);  // 3 KB each, so that frames do not allocate
  const int n = opt_.zncc.patch_size;
  for (size_t i = 0; i < warp_buf_.size(); ++i) {
    warp_buf_[i].resize(n, n);
    patches_[i].assign(warp_buf_[i].view());
  }
}

bool ActiveSearchDataManager::predict_patch(const slam::Map& map, const slam::Sensor& sensor,
                                            const slam::Observation& obs, int slot) {
  const PointDescriptor* desc = point_descriptor(*obs.landmark);
  const auto* cam_sensor = dynamic_cast<const slam::PinholeSensor*>(&sensor);
  if (desc == nullptr || cam_sensor == nullptr) return false;
  const models::PinholeCamera& camera = cam_sensor->camera();
  const models::CameraIntrinsics& in = camera.intrinsics();
  const Eigen::VectorXd& mean = map.state().mean_vector();
  const math::Pose T_WS = sensor.pose_in_world(mean);
  const Eigen::Vector3d p_W = obs.landmark->position(mean);
  const vision::PinholeIntrinsics K{in.fx, in.fy, in.cx, in.cy};
  const vision::RigidPose T_WC0{desc->T_WS0.q.toRotationMatrix(), desc->T_WS0.p};
  const vision::RigidPose T_WC{T_WS.q.toRotationMatrix(), T_WS.p};
  vision::LocalDistortion dist;
  const bool distorted = in.model != models::DistortionModel::None;
  if (distorted) {
    const Eigen::Vector3d p_C = T_WS.inverse_transform(p_W);
    if (!(p_C.z() > 0.0)) return false;
    Eigen::Vector2d xy_d;
    Eigen::Matrix2d J;
    if (!camera.distort(p_C.head<2>() / p_C.z(), xy_d, &J)) return false;
    const Eigen::Vector2d f(in.fx, in.fy);
    dist.J_dist_undist = f.asDiagonal() * J * f.cwiseInverse().asDiagonal();
    dist.J_dist_undist_0 = desc->J_dist_undist_0;
    dist.centre0_dist_px = desc->z0_px;
  }
  if (slot >= static_cast<int>(warp_buf_.size())) {
    warp_buf_.resize(static_cast<size_t>(slot) + 1);
    patches_.resize(static_cast<size_t>(slot) + 1);
    memos_.resize(static_cast<size_t>(slot) + 1);
  }
  vision::Image& buf = warp_buf_[static_cast<size_t>(slot)];
  const int n = opt_.zncc.patch_size;
  if (buf.width() != n || buf.height() != n) buf.resize(n, n);
  const vision::WarpResult w = vision::predict_appearance(desc->patch.view(), desc->patch_centre_px, K, T_WC0, T_WC,
                                                          p_W, buf.mutable_view(), distorted ? &dist : nullptr);
  // A prediction that needs much of its support from outside the stored patch is not trusted.
  if (!w.ok || w.n_outside > n * n / 4) return false;
  vision::Patch& patch = patches_[static_cast<size_t>(slot)];
  patch.assign(buf.view());
  vision::ScoreMemo& memo = memos_[static_cast<size_t>(slot)];
  if (memo.capacity() == 0) memo.reserve(kMemoEntries);  // a slot beyond the reserved ones (as warp_buf_ above)
  memo.clear();  // a new patch (and image): nothing it remembers holds
  return patch.centred_energy() > 0;
}

bool ActiveSearchDataManager::search(Candidate& c, const vision::SearchEllipse& region, vision::ZnccMatcher& matcher,
                                     Eigen::Vector2d& z, double& score) {
  ++searches_;
  const auto t0 = std::chrono::steady_clock::now();
  const vision::MatchResult r =
      matcher.match(patches_[static_cast<size_t>(c.slot)], image_, region, &memos_[static_cast<size_t>(c.slot)]);
  match_ms_ += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (!r.found) return false;
  z = Eigen::Vector2d(r.u, r.v);
  score = r.score;
  return true;
}

bool ActiveSearchDataManager::correct_batch(slam::Map& map, const std::vector<Candidate*>& batch) {
  batch_obs_.clear();
  for (Candidate* c : batch) {
    c->obs->z = c->z;
    batch_obs_.push_back(c->obs);
  }
  slam::BatchCorrectionOptions bo;
  bo.sigma_px = opt_.sigma_px;
  bo.second_order_depth = opt_.second_order_depth;
  bo.iterations = opt_.iterations;
  bo.iteration_tolerance = opt_.iteration_tolerance;
  bo.lin_mean = lin();
  // Both callers correct observations predicted with their Jacobians at the current mean: the RANSAC support set
  // (predicted in step 1, the state unchanged since: hypotheses work on a copy of the mean) and an active-search
  // round (each member predicted in that round, the state unchanged until this correction).
  bo.jacobians_current = true;
  const filter::CorrectionResult r = corrector_.correct(map.state(), batch_obs_, bo);
  return r.ok() && corrector_.used() > 0;
}

void ActiveSearchDataManager::process(slam::Map& map, slam::Sensor& sensor, const slam::RawData& raw, long frame,
                                      slam::FrameStats& stats) {
  using Clock = std::chrono::steady_clock;
  const auto* img = dynamic_cast<const RawImage*>(&raw);
  if (!img || img->image.empty()) throw ConfigError("active-search data manager: raw data is not an image");
  const auto t0 = Clock::now();
  image_ = img->image;
  if (img->image.width != reserved_width_ || img->image.height != reserved_height_) {
    // Search regions are bounded by max_search_size_px2: the matchers' buffers reach their final sizes now.
    reserved_width_ = img->image.width;
    reserved_height_ = img->image.height;
    // The fallback of min_candidates may search up to the whole image with the full-ellipse matcher.
    const double image_area = static_cast<double>(reserved_width_) * reserved_height_;
    matcher_.reserve(
        opt_.min_candidates > 0 ? std::max(opt_.max_search_size_px2, image_area) : opt_.max_search_size_px2,
        reserved_width_, reserved_height_);
    matcher_small_.reserve(opt_.max_search_size_px2, reserved_width_, reserved_height_);
  }
  filter::State& state = map.state();
  const double gate = opt_.n_sigma * opt_.n_sigma;
  if (dx_.size() != state.tangent_capacity()) dx_.setZero(state.tangent_capacity());
  if (hyp_mean_.size() != state.mean_vector().size()) hyp_mean_ = state.mean_vector();

  // First-estimate Jacobians: the robot (and sensor) at this frame's prediction, before its corrections;
  // Euclidean landmarks at their first estimate (made when their depth had converged); AHP landmarks, whose first
  // depth is the prior's, at the current mean.
  if (fej_) {
    fej_mean_ = state.mean_vector();
    for (const auto& l : map.landmarks()) {
      if (l->type() != slam::LandmarkType::EuclideanPoint) continue;
      const filter::BlockInfo& info = state.block(l->block());
      if (l->first_estimate.size() == info.ambient_size()) fej_mean_.segment(info.ambient_offset, info.ambient_size()) = l->first_estimate;
    }
  }

  // 1. Predict all observations; keep the visible ones with a reasonable search region and a predicted patch.
  grid_.reset(rng_);
  candidates_.clear();
  oversized_.clear();
  auto admit = [&](slam::Observation& o, bool fallback) {
    const int slot = static_cast<int>(candidates_.size());
    if (!predict_patch(map, sensor, o, slot)) return;
    stats.fallback += fallback ? 1 : 0;
    Candidate c;
    c.obs = &o;
    c.slot = slot;
    c.h0 = o.h;
    c.S0 = o.S;
    c.det0 = o.S.determinant();
    c.fallback = fallback;
    candidates_.push_back(c);
  };
  for (const auto& l : map.landmarks()) {
    slam::Observation* o = l->observation_of(sensor);
    if (o == nullptr) continue;
    // Out of the image (most of a global map): the projection alone says so; Jacobians only for the visible.
    if (!slam::predict_observation(state, state.mean_vector(), *o, opt_.margin_px, false)) continue;
    if (!slam::predict_observation(state, state.mean_vector(), *o, opt_.margin_px, true, lin())) continue;
    slam::compute_innovation_covariance(state, *o, opt_.sigma_px, opt_.second_order_depth);
    o->counters.last_visible_frame = frame;
    grid_.occupy(o->h);
    const vision::Roi box = vision::SearchEllipse::from_covariance(o->h, o->S, opt_.n_sigma).bounding_box();
    if (static_cast<double>(box.w) * box.h > opt_.max_search_size_px2) {
      if (opt_.min_candidates > 0) {
        const vision::Roi in = box.intersect(vision::Roi{0, 0, image_.width, image_.height});
        oversized_.push_back({static_cast<double>(in.w) * in.h, static_cast<int>(oversized_.size()), o});
      }
      continue;
    }
    admit(*o, false);
  }
  // Too few small boxes: the smallest oversized ones (ties: the map order) are searched as well. Their S and h are
  // still this frame's prediction (each observation is predicted once above).
  if (static_cast<int>(candidates_.size()) < opt_.min_candidates && !oversized_.empty()) {
    std::sort(oversized_.begin(), oversized_.end(), [](const Oversized& a, const Oversized& b) {
      return a.area < b.area || (a.area == b.area && a.order < b.order);
    });
    for (const Oversized& big : oversized_) {
      if (static_cast<int>(candidates_.size()) >= opt_.min_candidates) break;
      if (big.area > 0.0) admit(*big.obs, true);
    }
  }
  stats.visible = static_cast<int>(candidates_.size());
  // Expected information: the largest innovation covariance first, ties in the map order (a stable sort's order,
  // without its temporary buffer: the slot is the map order). The fallback's candidates come last: by the time the
  // active search reaches them, the corrections of the others have shrunk their boxes and their gate.
  order_.clear();
  for (Candidate& c : candidates_) order_.push_back(&c);
  std::sort(order_.begin(), order_.end(), [](const Candidate* a, const Candidate* b) {
    if (a->fallback != b->fallback) return b->fallback;
    return a->det0 > b->det0 || (a->det0 == b->det0 && a->slot < b->slot);
  });
  const auto t1 = Clock::now();

  auto count_search = [&](Candidate& c) {
    if (c.searched) return;
    c.searched = true;
    ++c.obs->counters.searched;
    ++stats.searched;
  };
  auto count_match = [&](Candidate& c) {
    if (c.matched) return;
    c.matched = true;
    ++c.obs->counters.matched;
    ++stats.matched;
    const Eigen::Vector2d y0 = c.z - c.h0;
    stats.nis += y0.dot(c.S0.ldlt().solve(y0));
    ++stats.nis_count;
  };
  auto count_fail = [&](Candidate& c) {
    c.done = true;
    ++c.obs->counters.failed;
  };
  auto count_update = [&](Candidate& c, bool ok) {
    c.done = true;
    if (!ok) {
      ++c.obs->counters.failed;
      return;
    }
    c.updated = true;
    ++c.obs->counters.updated;
    c.obs->counters.last_updated_frame = frame;
    ++stats.updated;
  };

  // 2. One-point RANSAC with data association. The search budget (if any) starts now.
  match_ms_ = 0.0;
  searches_ = 0;
  budget_spent_ = false;
  const bool budgeted = opt_.time_budget_ms > 0.0;
  if (budgeted) budget_start_ms_ = clock_->now_ms();
  if (opt_.ransac_ntries > 0 && opt_.max_updates_ransac >= 2 && candidates_.size() >= 2) {
    untried_.clear();
    for (Candidate* c : order_) untried_.push_back(c->slot);
    best_support_.clear();
    best_support_z_.clear();
    int hypotheses = 0;
    for (int t = 0; t < opt_.ransac_ntries && !untried_.empty(); ++t) {
      if (!may_search()) break;  // the budget is spent: no new hypothesis (each needs a full-ellipse search)
      const auto k = std::uniform_int_distribution<size_t>(0, untried_.size() - 1)(rng_);
      const int i = untried_[k];
      untried_.erase(untried_.begin() + static_cast<std::ptrdiff_t>(k));
      Candidate& ci = candidates_[static_cast<size_t>(i)];
      ci.tried = true;
      if (!ci.full_searched) {
        ci.full_searched = true;
        count_search(ci);
        ci.full_matched = search(ci, vision::SearchEllipse::from_covariance(ci.h0, ci.S0, opt_.n_sigma), matcher_,
                                 ci.z, ci.score);
        if (ci.full_matched) count_match(ci);
      }
      if (!ci.full_matched) continue;
      // The one-point state: mean only. (Observations still hold H and S of the first prediction.)
      const slam::Observation& oi = *ci.obs;
      const Eigen::Vector2d y = ci.z - ci.h0;
      if (!state.mean_correction(oi.involved(), oi.H, y, oi.R, dx_).ok()) {
        continue;
      }
      state.boxplus_all(state.mean_vector(), dx_, hyp_mean_);
      support_.assign(1, i);
      support_z_.assign(1, ci.z);
      for (Candidate* cj : order_) {
        if (cj->slot == i) continue;
        slam::Observation& oj = *cj->obs;
        if (!slam::predict_observation(state, hyp_mean_, oj, 0.0, false) || !oj.projectable) continue;
        if (!may_search()) break;  // the budget is spent: the support found so far competes as it is
        Eigen::Vector2d z;
        double score = 0.0;
        if (search(*cj, vision::SearchEllipse::box(oj.h, opt_.ransac_low_innov_px, opt_.ransac_low_innov_px),
                   matcher_small_, z, score)) {
          support_.push_back(cj->slot);
          support_z_.push_back(z);
        }
      }
      if (support_.size() > best_support_.size()) {
        best_support_.swap(support_);
        best_support_z_.swap(support_z_);
      }
      // Only hypotheses count (a draw whose full search found nothing gave none to test).
      ++hypotheses;
      if (ransac_may_stop(hypotheses, static_cast<int>(best_support_.size()), static_cast<int>(candidates_.size()),
                          opt_.ransac_confidence)) {
        break;
      }
    }
    stats.ransac_hypotheses = hypotheses;
    if (hypotheses > 0) stats.ransac_max = opt_.max_updates_ransac;
    if (best_support_.size() >= 2) {
      batch_.clear();
      const size_t n = std::min(best_support_.size(), static_cast<size_t>(opt_.max_updates_ransac));
      for (size_t s = 0; s < n; ++s) {
        Candidate& c = candidates_[static_cast<size_t>(best_support_[s])];
        count_search(c);
        c.z = best_support_z_[s];
        count_match(c);
        c.inlier = true;
        batch_.push_back(&c);
      }
      const bool ok = correct_batch(map, batch_);
      if (!ok) ++stats.refused;
      for (Candidate* c : batch_) count_update(*c, ok);
      stats.ransac_inliers = static_cast<int>(n);
    }
  }

  const auto t_ransac = Clock::now();
  const double ransac_match_ms = match_ms_;

  // 3. Active search of the rest at the corrected state, gated, in N_RECOMP_GAINS batched rounds.
  size_t next = 0;
  for (int round = 0; round < opt_.gain_recomputations && next < order_.size() && stats.updated < opt_.max_updates;
       ++round) {
    batch_.clear();
    const int left = opt_.max_updates - stats.updated;
    const int rounds_left = opt_.gain_recomputations - round;
    const int budget = std::min(kMaxBatch, (left + rounds_left - 1) / rounds_left);
    while (next < order_.size() && static_cast<int>(batch_.size()) < budget) {
      Candidate& c = *order_[next++];
      if (c.done) continue;
      if (budget_spent_ && !c.full_searched) {  // the budget is spent: skipped, not even re-predicted
        ++stats.budget_skipped;
        continue;
      }
      slam::Observation& o = *c.obs;
      if (!slam::predict_observation(state, state.mean_vector(), o, 0.0, true, lin())) continue;
      slam::compute_innovation_covariance(state, o, opt_.sigma_px, opt_.second_order_depth);
      const vision::SearchEllipse region = vision::SearchEllipse::from_covariance(o.h, o.S, opt_.n_sigma);
      const vision::Roi box = region.bounding_box();
      // A candidate of the min_candidates fallback is searched whatever its box (the matcher holds the image).
      if (!c.fallback && static_cast<double>(box.w) * box.h > opt_.max_search_size_px2) continue;
      bool found = c.full_matched;  // a RANSAC hypothesis that lost keeps its full-ellipse match (gated below)
      if (!c.full_searched) {
        if (!may_search()) {  // the budget is spent: skipped, neither searched nor failed
          ++stats.budget_skipped;
          continue;
        }
        count_search(c);
        found = search(c, region, matcher_, c.z, c.score);
      }
      if (!found) {
        count_fail(c);
        continue;
      }
      count_match(c);
      o.y = c.z - o.h;
      o.mahalanobis2 = o.y.dot(o.S.ldlt().solve(o.y));
      if (!(o.mahalanobis2 <= gate)) {
        count_fail(c);
        continue;
      }
      batch_.push_back(&c);
    }
    if (batch_.empty()) continue;
    const bool ok = correct_batch(map, batch_);
    if (!ok) ++stats.refused;
    for (Candidate* c : batch_) count_update(*c, ok);
  }
  // The frame's corrections left their covariance downdate pending (filter/state.hpp); initialization and the next
  // prediction need it applied: done here, so that its cost shows as the update's.
  state.apply_pending();
  const auto t2 = Clock::now();
  stats.budget_hit = budget_spent_;
  stats.time_search_ms = budgeted ? clock_->now_ms() - budget_start_ms_
                                  : std::chrono::duration<double, std::milli>(t2 - t1).count();

  // 4. Initialization in the empty cells of the moving grid.
  initialize(map, sensor, frame, stats);
  const auto t3 = Clock::now();

  report_.clear();
  for (const Candidate& c : candidates_) {
    FrameMatch m;
    m.landmark_id = c.obs->landmark->id();
    m.h = c.h0;
    m.S = c.S0;
    m.z = c.z;
    m.score = c.score;
    m.searched = c.searched;
    m.matched = c.matched;
    m.ransac_inlier = c.inlier;
    m.updated = c.updated;
    report_.push_back(m);
  }
  stats.time_predict_ms += std::chrono::duration<double, std::milli>(t1 - t0).count();
  stats.time_match_ms = match_ms_;
  stats.time_ransac_ms = std::chrono::duration<double, std::milli>(t_ransac - t1).count() - ransac_match_ms;
  stats.time_update_ms = std::chrono::duration<double, std::milli>(t2 - t_ransac).count() - (match_ms_ - ransac_match_ms);
  stats.time_init_ms = std::chrono::duration<double, std::milli>(t3 - t2).count();
}

models::AhpPrior ActiveSearchDataManager::frame_prior(const slam::Map& map, const slam::Sensor& sensor) {
  if (opt_.depth_prior == "fixed") return opt_.prior;
  const Eigen::VectorXd& mean = map.state().mean_vector();
  const Eigen::Vector3d p_WS = sensor.pose_in_world(mean).p;
  depths_.clear();
  for (const Candidate& c : candidates_) {
    if (!c.updated || c.obs->landmark->type() != slam::LandmarkType::EuclideanPoint) continue;
    depths_.push_back((c.obs->landmark->position(mean) - p_WS).norm());
  }
  if (static_cast<int>(depths_.size()) < opt_.scene_prior_min_points) {
    if (depth_hint_m_ <= 0.0) return opt_.prior;
    models::AhpPrior hinted = opt_.prior;
    hinted.d_min = 0.5 * depth_hint_m_;
    return hinted;
  }
  const auto mid = depths_.begin() + static_cast<std::ptrdiff_t>(depths_.size() / 2);
  std::nth_element(depths_.begin(), mid, depths_.end());
  models::AhpPrior p = opt_.prior;
  p.d_min = 0.5 * *mid;
  return p.d_min > 0.0 && std::isfinite(p.d_min) ? p : opt_.prior;
}

void ActiveSearchDataManager::initialize(slam::Map& map, slam::Sensor& sensor, long frame, slam::FrameStats& stats) {
  const auto* cam_sensor = dynamic_cast<const slam::PinholeSensor*>(&sensor);
  if (cam_sensor == nullptr) return;
  const models::PinholeCamera& camera = cam_sensor->camera();
  const models::CameraIntrinsics& in = camera.intrinsics();
  const int half = opt_.init_patch_size / 2;
  const models::AhpPrior prior = frame_prior(map, sensor);
  int inits = 0;
  for (int cell : grid_.empty_cells(rng_)) {
    if (inits >= opt_.max_inits || !map_manager_.has_room(map, 7)) break;
    const Eigen::Vector4d r = grid_.cell_rect(cell);
    const int x0 = static_cast<int>(std::ceil(r[0])), y0 = static_cast<int>(std::ceil(r[1]));
    const int x1 = static_cast<int>(std::ceil(r[2])), y1 = static_cast<int>(std::ceil(r[3]));
    const vision::Roi roi{x0, y0, x1 - x0, y1 - y0};
    if (roi.empty()) continue;
    const auto corner = harris_.best_corner(image_, roi);
    if (!corner) continue;
    if (corner->u_px - half < 0 || corner->v_px - half < 0 || corner->u_px + half >= image_.width ||
        corner->v_px + half >= image_.height) {
      continue;
    }
    const Eigen::Vector2d z(corner->u, corner->v);
    Eigen::Vector3d ray;
    if (!camera.unproject(z, ray)) continue;
    Eigen::Vector2d xy_d;
    Eigen::Matrix2d J = Eigen::Matrix2d::Identity();
    if (!camera.distort(ray.head<2>(), xy_d, &J)) continue;
    const math::Pose T_WS = sensor.pose_in_world(map.state().mean_vector());
    slam::Landmark* l = slam::init_ahp_landmark(map, sensor, z, opt_.sigma_px, prior, frame);
    if (l == nullptr) break;
    auto desc = std::make_shared<PointDescriptor>();
    desc->patch = vision::Image::copy_of(
        image_.roi(corner->u_px - half, corner->v_px - half, opt_.init_patch_size, opt_.init_patch_size));
    desc->patch_centre_px = Eigen::Vector2d(corner->u_px, corner->v_px);
    desc->z0_px = z;
    const Eigen::Vector2d f(in.fx, in.fy);
    desc->J_dist_undist_0 = f.asDiagonal() * J * f.cwiseInverse().asDiagonal();
    desc->T_WS0 = T_WS;
    l->descriptor = PointDescriptorPtr(std::move(desc));
    grid_.occupy(z);
    ++inits;
  }
  stats.initialized = inits;
}

}  // namespace rtslam::strategies
