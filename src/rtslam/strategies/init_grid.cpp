#include "rtslam/strategies/init_grid.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"

namespace rtslam::strategies {

void InitGridOptions::validate(const std::string& where) const {
  require_bound(cells_x >= 1 && cells_x <= kMaxCells, where, "cells_x", cells_x, fmt::format("in [1, {}]", kMaxCells));
  require_bound(cells_y >= 1 && cells_y <= kMaxCells, where, "cells_y", cells_y, fmt::format("in [1, {}]", kMaxCells));
  require_bound(margin_px >= 0.0 && margin_px <= 1000.0, where, "margin_px", margin_px, "in [0, 1000] px");
}

InitGrid::InitGrid(int width, int height, InitGridOptions options) : width_(width), height_(height), opt_(options) {
  opt_.validate("search/grid");
  // Cells narrower than a few pixels hold no corner of their own (and a grid of tiny cells costs time per frame).
  const double cell_w = (width_ - 2.0 * opt_.margin_px) / opt_.cells_x;
  const double cell_h = (height_ - 2.0 * opt_.margin_px) / opt_.cells_y;
  if (!(cell_w >= InitGridOptions::kMinCellPx && cell_h >= InitGridOptions::kMinCellPx)) {
    throw ConfigError(fmt::format("search/grid: cells_x = {}, cells_y = {} and margin_px = {} give cells of {:.1f}x{:.1f} "
                                  "px on the {}x{} px image: they must be at least {} px",
                                  opt_.cells_x, opt_.cells_y, opt_.margin_px, cell_w, cell_h, width_, height_,
                                  InitGridOptions::kMinCellPx));
  }
  // The moving grid has one extra row/column of cells so the shifted grid still covers the image.
  cell_w_ = (width_ - 2.0 * opt_.margin_px) / opt_.cells_x;
  cell_h_ = (height_ - 2.0 * opt_.margin_px) / opt_.cells_y;
  occupied_.assign(static_cast<size_t>((opt_.cells_x + 1) * (opt_.cells_y + 1)), 0);
  empty_.reserve(occupied_.size());
}

void InitGrid::reset(Rng& rng) {
  off_x_ = randu(rng, 0.0, cell_w_);
  off_y_ = randu(rng, 0.0, cell_h_);
  std::fill(occupied_.begin(), occupied_.end(), 0);
}

int InitGrid::cell_of(const Eigen::Vector2d& z) const {
  const double x = z.x() - opt_.margin_px + off_x_;
  const double y = z.y() - opt_.margin_px + off_y_;
  if (x < 0.0 || y < 0.0) return -1;
  const int cx = static_cast<int>(x / cell_w_);
  const int cy = static_cast<int>(y / cell_h_);
  if (cx > opt_.cells_x || cy > opt_.cells_y) return -1;
  return cy * (opt_.cells_x + 1) + cx;
}

void InitGrid::occupy(const Eigen::Vector2d& z) {
  const int c = cell_of(z);
  if (c >= 0) occupied_[static_cast<size_t>(c)] = 1;
}

Eigen::Vector4d InitGrid::cell_rect(int cell) const {
  const int cx = cell % (opt_.cells_x + 1);
  const int cy = cell / (opt_.cells_x + 1);
  const double x0 = std::max(opt_.margin_px, opt_.margin_px - off_x_ + cx * cell_w_);
  const double y0 = std::max(opt_.margin_px, opt_.margin_px - off_y_ + cy * cell_h_);
  const double x1 = std::min(width_ - opt_.margin_px, opt_.margin_px - off_x_ + (cx + 1) * cell_w_);
  const double y1 = std::min(height_ - opt_.margin_px, opt_.margin_px - off_y_ + (cy + 1) * cell_h_);
  return {x0, y0, x1, y1};
}

const std::vector<int>& InitGrid::empty_cells(Rng& rng) {
  empty_.clear();
  for (int c = 0; c < cell_count(); ++c) {
    if (occupied_[static_cast<size_t>(c)]) continue;
    const Eigen::Vector4d r = cell_rect(c);
    // Skip slivers: a cell must keep at least half its size inside the margins.
    if ((r[2] - r[0]) < 0.5 * cell_w_ || (r[3] - r[1]) < 0.5 * cell_h_) continue;
    empty_.push_back(c);
  }
  std::shuffle(empty_.begin(), empty_.end(), rng);
  return empty_;
}

}  // namespace rtslam::strategies
