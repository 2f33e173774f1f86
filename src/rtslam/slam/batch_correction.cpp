#include "rtslam/slam/batch_correction.hpp"

#include "rtslam/core/error.hpp"
#include "rtslam/slam/landmark.hpp"

namespace rtslam::slam {

BatchCorrector::BatchCorrector(int max_observations) : max_obs_(max_observations) {
  RTSLAM_CHECK(max_observations >= 1, "BatchCorrector needs room for at least one observation");
  const int max_cols = 64 + kMaxLandmarkTangent * max_observations;
  blocks_.reserve(static_cast<std::size_t>(max_observations) + 3);  // + robot, extrinsics, time offset
  used_flags_.reserve(static_cast<std::size_t>(max_observations));
  H_.resize(2 * max_observations, max_cols);
  R_.resize(2 * max_observations, 2 * max_observations);
  y_.resize(2 * max_observations);
  iter_dx_.setZero(max_cols);
  iter_dx_prev_.setZero(max_cols);
}

void BatchCorrector::assemble(const filter::State& state, std::span<Observation* const> batch,
                              const BatchCorrectionOptions& o) {
  auto H = H_.topLeftCorner(rows_, cols_);
  auto R = R_.topLeftCorner(rows_, rows_);
  H.setZero();
  R.setZero();
  int row = 0;
  int col = shared_cols_;
  for (std::size_t k = 0; k < batch.size(); ++k) {
    const Observation* ob = batch[k];
    if (!used_flags_[k]) continue;
    const int tl = state.block(ob->landmark_block()).tangent_size();
    H.block(row, 0, 2, shared_cols_) = ob->H.leftCols(shared_cols_);
    H.block(row, col, 2, tl) = ob->H.rightCols(tl);
    y_.segment<2>(row) = ob->z - ob->h;
    R.block<2, 2>(row, row) = measurement_noise(*ob, o.sigma_px, o.second_order_depth);
    row += 2;
    col += tl;
  }
}

filter::CorrectionResult BatchCorrector::correct(filter::State& state, std::span<Observation* const> batch,
                                                 const BatchCorrectionOptions& o) {
  RTSLAM_CHECK(static_cast<int>(batch.size()) <= max_obs_, "BatchCorrector: batch larger than its workspaces");
  used_ = 0;
  cols_ = 0;
  blocks_.clear();
  used_flags_.assign(batch.size(), 0);
  for (std::size_t k = 0; k < batch.size(); ++k) {
    Observation* ob = batch[k];
    if (!predict_observation(state, state.mean_vector(), *ob, 0.0, !o.jacobians_current, o.lin_mean) ||
        !ob->projectable) {
      ob->projectable = false;
      continue;
    }
    used_flags_[k] = 1;
    if (blocks_.empty()) {
      for (const filter::BlockId b : ob->sensor_blocks()) blocks_.push_back(b);
      shared_cols_ = static_cast<int>(ob->H.cols()) - state.block(ob->landmark_block()).tangent_size();
      cols_ = shared_cols_;
    }
    blocks_.push_back(ob->landmark_block());
    cols_ += state.block(ob->landmark_block()).tangent_size();
    ++used_;
  }
  if (used_ == 0) return {};
  rows_ = 2 * used_;
  assemble(state, batch, o);
  auto H = H_.topLeftCorner(rows_, cols_);
  auto R = R_.topLeftCorner(rows_, rows_);
  auto y = y_.head(rows_);
  const int iterations = o.lin_mean != nullptr ? 1 : o.iterations;
  for (int it = 1; it < iterations; ++it) {
    if (dx_.size() != state.tangent_capacity()) dx_.setZero(state.tangent_capacity());
    if (!state.mean_correction(blocks_, H, y, R, dx_).ok()) break;
    // dx over the batch's blocks in H's column order (x_i ⊖ x is dx itself on them).
    int c = 0;
    for (const filter::BlockId b : blocks_) {
      const filter::BlockInfo& info = state.block(b);
      iter_dx_.segment(c, info.tangent_size()) = dx_.segment(info.tangent_offset, info.tangent_size());
      c += info.tangent_size();
    }
    if (it > 1 && (iter_dx_.head(cols_) - iter_dx_prev_.head(cols_)).cwiseAbs().maxCoeff() < o.iteration_tolerance) {
      break;
    }
    iter_dx_prev_.head(cols_) = iter_dx_.head(cols_);
    if (iter_mean_.size() != state.mean_vector().size()) iter_mean_ = state.mean_vector();
    state.boxplus_all(state.mean_vector(), dx_, iter_mean_);
    bool projectable = true;
    for (std::size_t k = 0; k < batch.size(); ++k) {
      if (!used_flags_[k]) continue;
      predict_observation(state, iter_mean_, *batch[k], 0.0, true);
      projectable = projectable && batch[k]->projectable;
    }
    if (!projectable) {  // an iterate left a projection's domain: back to the linearization at the mean
      for (std::size_t k = 0; k < batch.size(); ++k) {
        if (used_flags_[k]) predict_observation(state, state.mean_vector(), *batch[k], 0.0, true);
      }
      assemble(state, batch, o);
      break;
    }
    assemble(state, batch, o);
    y.noalias() += H * iter_dx_.head(cols_);
  }
  return state.correct(blocks_, H, y, R);
}

}  // namespace rtslam::slam
