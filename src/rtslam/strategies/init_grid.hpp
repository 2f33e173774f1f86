#pragma once
// RT-SLAM's randomly moving grid for feature initialization: a fixed grid of cells (6x4 by default) shifted by a
// random offset every frame; new features are sought only in cells that hold no landmark observation.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/random.hpp"

namespace rtslam::strategies {

struct InitGridOptions {
  int cells_x = 6;
  int cells_y = 4;
  double margin_px = 8.0;  // cells are kept this far from the image border
  static constexpr int kMaxCells = 64;          // cells_x, cells_y in [1, kMaxCells]
  static constexpr double kMinCellPx = 4.0;     // InitGrid refuses smaller cells on its image
  /// `where` names the options in messages (their config section, e.g. "search/zncc", or the file and section).
  void validate(const std::string& where = "init grid") const;
};

class InitGrid {
 public:
  /// Throws ConfigError (naming search/grid) when the options or the cells they give on this image are out of bounds.
  InitGrid(int width, int height, InitGridOptions options);
  /// New random offset (in [0, cell size)) and all cells empty.
  void reset(Rng& rng);
  /// Marks the cell containing pixel z as occupied (ignored outside the grid).
  void occupy(const Eigen::Vector2d& z);
  /// Index of the cell containing z, or -1 outside the grid.
  int cell_of(const Eigen::Vector2d& z) const;
  bool occupied(int cell) const { return occupied_[static_cast<size_t>(cell)]; }
  int cell_count() const { return static_cast<int>(occupied_.size()); }
  /// Pixel rectangle of a cell: [x0, x1) x [y0, y1), clipped to the margins.
  Eigen::Vector4d cell_rect(int cell) const;
  /// Empty cells in a random order.
  const std::vector<int>& empty_cells(Rng& rng);

 private:
  int width_;
  int height_;
  InitGridOptions opt_;
  double cell_w_;
  double cell_h_;
  double off_x_ = 0.0;
  double off_y_ = 0.0;
  std::vector<char> occupied_;
  std::vector<int> empty_;
};

}  // namespace rtslam::strategies
