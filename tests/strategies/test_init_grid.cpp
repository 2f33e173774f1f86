// The randomly moving initialization grid (paper, section 4.1: "each sensor strives to maintain features in its whole
// field of view using a randomly moving grid of fixed size, and feature detection is limited to empty cells"):
// the grid's offset is redrawn every frame, uniformly over a cell and reproducibly from the seed; the cells it offers
// hold no occupied pixel, stay inside the margins, and over the frames reach every part of the image, also the
// parts next to a landmark that a fixed grid would keep blocked. Last, the active-search data manager puts its new
// landmarks only into cells where no landmark projects.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <set>
#include <vector>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/strategies/active_search.hpp"
#include "rtslam/strategies/init_grid.hpp"
#include "rtslam/strategies/map_policies.hpp"
#include "strategies/strategy_rig.hpp"

namespace rtslam::strategies {
namespace {

constexpr int kWidth = 320;
constexpr int kHeight = 240;

struct Geometry {
  InitGridOptions opt;
  double cell_w = 0.0;
  double cell_h = 0.0;
  explicit Geometry(InitGridOptions o = {}) : opt(o) {
    cell_w = (kWidth - 2.0 * opt.margin_px) / opt.cells_x;
    cell_h = (kHeight - 2.0 * opt.margin_px) / opt.cells_y;
  }
};

/// The grid's offset, read through the public interface: cell (1, 1) starts at margin − offset + cell size (never
/// clipped, since the offset is below one cell).
Eigen::Vector2d offset_of(const InitGrid& grid, const Geometry& g) {
  const Eigen::Vector4d r = grid.cell_rect((g.opt.cells_x + 1) + 1);
  return {g.opt.margin_px + g.cell_w - r[0], g.opt.margin_px + g.cell_h - r[1]};
}

bool inside(const Eigen::Vector4d& r, const Eigen::Vector2d& z) {
  return z.x() >= r[0] && z.x() < r[2] && z.y() >= r[1] && z.y() < r[3];
}

double correlation(const std::vector<double>& a, const std::vector<double>& b) {
  const auto n = static_cast<double>(a.size());
  double ma = 0, mb = 0;
  for (size_t i = 0; i < a.size(); ++i) ma += a[i] / n, mb += b[i] / n;
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    sab += (a[i] - ma) * (b[i] - mb);
    saa += (a[i] - ma) * (a[i] - ma);
    sbb += (b[i] - mb) * (b[i] - mb);
  }
  return sab / std::sqrt(saa * sbb);
}

/// χ² statistic of `values` (in [0, range)) against the uniform distribution over `bins` bins.
double chi2_uniform(const std::vector<double>& values, double range, int bins) {
  std::vector<int> count(static_cast<size_t>(bins), 0);
  for (double v : values) ++count[static_cast<size_t>(std::min(bins - 1, static_cast<int>(v / range * bins)))];
  const double expected = static_cast<double>(values.size()) / bins;
  double chi2 = 0;
  for (int c : count) chi2 += (c - expected) * (c - expected) / expected;
  return chi2;
}

TEST(InitGrid, OffsetIsRedrawnEveryFrameUniformlyOverACell) {
  const Geometry g;
  InitGrid grid(kWidth, kHeight, g.opt);
  Rng rng(11);
  constexpr int kFrames = 2000;
  std::vector<double> ox, oy;
  for (int f = 0; f < kFrames; ++f) {
    grid.reset(rng);
    const Eigen::Vector2d o = offset_of(grid, g);
    ASSERT_GE(o.x(), -1e-9);
    ASSERT_LT(o.x(), g.cell_w);
    ASSERT_GE(o.y(), -1e-9);
    ASSERT_LT(o.y(), g.cell_h);
    if (f > 0) {
      EXPECT_GT(std::abs(o.x() - ox.back()), 1e-9) << "frame " << f << ": the grid did not move along x";
      EXPECT_GT(std::abs(o.y() - oy.back()), 1e-9) << "frame " << f << ": the grid did not move along y";
    }
    ox.push_back(std::max(0.0, o.x()));
    oy.push_back(std::max(0.0, o.y()));
  }
  // Uniform over the cell: χ² with 9 dof stays below 30 (p ≈ 4e-4) for a uniform draw; a fixed or few-valued
  // pattern, or offsets kept to part of the cell, are far above.
  EXPECT_LT(chi2_uniform(ox, g.cell_w, 10), 30.0);
  EXPECT_LT(chi2_uniform(oy, g.cell_h, 10), 30.0);
  // Not a pattern: no value repeats (no cycle), consecutive offsets are uncorrelated (a constant step modulo the
  // cell is not), and x and y are drawn independently.
  std::set<double> distinct_x(ox.begin(), ox.end()), distinct_y(oy.begin(), oy.end());
  EXPECT_EQ(distinct_x.size(), ox.size());
  EXPECT_EQ(distinct_y.size(), oy.size());
  for (int lag = 1; lag <= 3; ++lag) {
    const std::vector<double> ax(ox.begin(), ox.end() - lag), bx(ox.begin() + lag, ox.end());
    const std::vector<double> ay(oy.begin(), oy.end() - lag), by(oy.begin() + lag, oy.end());
    EXPECT_LT(std::abs(correlation(ax, bx)), 0.1) << "lag " << lag;
    EXPECT_LT(std::abs(correlation(ay, by)), 0.1) << "lag " << lag;
  }
  EXPECT_LT(std::abs(correlation(ox, oy)), 0.1);
}

TEST(InitGrid, SameSeedSameOffsetsAnotherSeedOthers) {
  const Geometry g;
  auto offsets = [&](std::uint64_t seed) {
    InitGrid grid(kWidth, kHeight, g.opt);
    Rng rng(seed);
    std::vector<Eigen::Vector2d> o;
    for (int f = 0; f < 50; ++f) {
      grid.reset(rng);
      o.push_back(offset_of(grid, g));
    }
    return o;
  };
  const auto a = offsets(3), b = offsets(3), c = offsets(4);
  EXPECT_EQ(a, b);
  int same = 0;
  for (size_t i = 0; i < a.size(); ++i) same += (a[i] - c[i]).norm() < 1e-9;
  EXPECT_EQ(same, 0);
}

// Each frame a random set of pixels (projected landmarks) is occupied: every offered cell holds none of them and
// every cell that holds none (and is not a sliver at the border) is offered, once.
TEST(InitGrid, OffersExactlyTheCellsWithoutAnOccupiedPixel) {
  const Geometry g;
  InitGrid grid(kWidth, kHeight, g.opt);
  Rng rng(5);
  int offered_total = 0, blocked_total = 0;
  for (int f = 0; f < 300; ++f) {
    grid.reset(rng);
    std::vector<Eigen::Vector2d> zs;
    const int n = static_cast<int>(randu(rng, 0, 30));
    for (int k = 0; k < n; ++k) {
      zs.emplace_back(randu(rng, g.opt.margin_px, kWidth - g.opt.margin_px),
                      randu(rng, g.opt.margin_px, kHeight - g.opt.margin_px));
      grid.occupy(zs.back());
      const int c = grid.cell_of(zs.back());
      ASSERT_GE(c, 0);
      EXPECT_TRUE(grid.occupied(c));
      EXPECT_TRUE(inside(grid.cell_rect(c), zs.back())) << "cell_of and cell_rect disagree";
    }
    const std::vector<int> empty = grid.empty_cells(rng);
    const std::set<int> offered(empty.begin(), empty.end());
    EXPECT_EQ(offered.size(), empty.size()) << "a cell offered twice";
    for (int c = 0; c < grid.cell_count(); ++c) {
      const Eigen::Vector4d r = grid.cell_rect(c);
      const bool holds = std::any_of(zs.begin(), zs.end(), [&](const Eigen::Vector2d& z) { return inside(r, z); });
      const bool sliver = r[2] - r[0] < 0.5 * g.cell_w || r[3] - r[1] < 0.5 * g.cell_h;
      if (offered.count(c)) {
        EXPECT_FALSE(holds) << "frame " << f << ": cell " << c << " holds a landmark but is offered";
        EXPECT_FALSE(grid.occupied(c));
      } else if (!holds && !sliver) {
        ADD_FAILURE() << "frame " << f << ": cell " << c << " is empty but not offered";
      }
      blocked_total += holds;
    }
    offered_total += static_cast<int>(empty.size());
  }
  EXPECT_GT(blocked_total, 1000);  // the test did exercise occupied cells
  EXPECT_GT(offered_total, 1000);
}

// The offered cells lie inside the margins and keep at least half a cell: features are sought neither at the border
// nor in slivers.
TEST(InitGrid, OfferedCellsRespectTheMargins) {
  for (double margin : {0.0, 8.0, 20.0}) {
    InitGridOptions o;
    o.margin_px = margin;
    o.cells_x = 5;
    o.cells_y = 3;
    const Geometry g(o);
    InitGrid grid(kWidth, kHeight, o);
    Rng rng(9);
    for (int f = 0; f < 200; ++f) {
      grid.reset(rng);
      for (int c : grid.empty_cells(rng)) {
        const Eigen::Vector4d r = grid.cell_rect(c);
        EXPECT_GE(r[0], margin);
        EXPECT_GE(r[1], margin);
        EXPECT_LE(r[2], kWidth - margin);
        EXPECT_LE(r[3], kHeight - margin);
        EXPECT_GE(r[2] - r[0], 0.5 * g.cell_w - 1e-9);
        EXPECT_GE(r[3] - r[1], 0.5 * g.cell_h - 1e-9);
      }
    }
  }
}

// Over the frames the offered cells reach every pixel inside the margins (no border strip, no cell boundary left out)
// and every cell index is used.
TEST(InitGrid, EveryPartOfTheImageIsEventuallyOffered) {
  const Geometry g;
  InitGrid grid(kWidth, kHeight, g.opt);
  Rng rng(21);
  const int m = static_cast<int>(g.opt.margin_px);
  std::vector<char> reached(static_cast<size_t>(kWidth * kHeight), 0);
  std::vector<char> index_used(static_cast<size_t>(grid.cell_count()), 0);
  for (int f = 0; f < 100; ++f) {
    grid.reset(rng);
    for (int c : grid.empty_cells(rng)) {
      index_used[static_cast<size_t>(c)] = 1;
      const Eigen::Vector4d r = grid.cell_rect(c);
      for (int v = static_cast<int>(std::ceil(r[1])); v < r[3]; ++v)
        for (int u = static_cast<int>(std::ceil(r[0])); u < r[2]; ++u) reached[static_cast<size_t>(v * kWidth + u)] = 1;
    }
  }
  int missed = 0;
  for (int v = m; v < kHeight - m; ++v)
    for (int u = m; u < kWidth - m; ++u) missed += !reached[static_cast<size_t>(v * kWidth + u)];
  EXPECT_EQ(missed, 0) << "pixels inside the margins never offered in 100 frames";
  for (int c = 0; c < grid.cell_count(); ++c) EXPECT_TRUE(index_used[static_cast<size_t>(c)]) << "cell " << c;
}

// A landmark blocks its cell; a pixel 0.4 cells away would share that cell forever in a fixed grid. The moving grid
// separates them in about 40 % of the frames along that axis: the neighbourhood of a landmark gets initialized too.
TEST(InitGrid, ThePixelsNextToALandmarkAreOfferedInSomeFrames) {
  const Geometry g;
  InitGrid grid(kWidth, kHeight, g.opt);
  Rng rng(2);
  const Eigen::Vector2d landmark(g.opt.margin_px + 2.5 * g.cell_w, g.opt.margin_px + 1.5 * g.cell_h);
  const Eigen::Vector2d near = landmark + Eigen::Vector2d(0.4 * g.cell_w, 0.0);
  int offered = 0;
  constexpr int kFrames = 400;
  for (int f = 0; f < kFrames; ++f) {
    grid.reset(rng);
    grid.occupy(landmark);
    for (int c : grid.empty_cells(rng)) offered += inside(grid.cell_rect(c), near);
  }
  EXPECT_GT(offered, 0.3 * kFrames);
  EXPECT_LT(offered, 0.5 * kFrames);
}

TEST(InitGridOptions, RejectsEmptyGridsAndNegativeMargins) {
  InitGridOptions o;
  o.cells_x = 0;
  EXPECT_THROW(InitGrid(kWidth, kHeight, o), ConfigError);
  o = {};
  o.margin_px = -1;
  EXPECT_THROW(o.validate(), ConfigError);
}

// ---------------------------------------------------------------------------------------------------------------
// Through the data manager: each frame, a random set of landmarks is placed at random pixels; the new landmarks
// the frame initializes lie in distinct cells of that frame's grid, none of which holds a projected landmark.

vision::Image random_rectangles(std::uint64_t seed) {
  Rng rng(seed);
  vision::Image img(kWidth, kHeight, 128);
  for (int k = 0; k < 600; ++k) {
    const int w = static_cast<int>(randu(rng, 4, 24)), h = static_cast<int>(randu(rng, 4, 24));
    const int x = static_cast<int>(randu(rng, 0, kWidth - w)), y = static_cast<int>(randu(rng, 0, kHeight - h));
    const auto grey = static_cast<std::uint8_t>(randu(rng, 15, 240));
    for (int v = y; v < y + h; ++v)
      for (int u = x; u < x + w; ++u) img.at(u, v) = grey;
  }
  return img;
}

TEST(ActiveSearchInitialization, NewLandmarksGoOnlyIntoCellsWithoutAProjectedLandmark) {
  testing::StrategyRig rig;
  PolicyMapManager mm{MapPolicyOptions{}};
  ActiveSearchOptions opt;
  opt.max_inits = 40;  // no cap below the number of cells: every empty cell with a corner gets a landmark
  ActiveSearchDataManager dm(opt, mm, kWidth, kHeight, 17);
  const vision::Image img = random_rectangles(8);
  RawImage raw;
  raw.image = img.view();
  Rng rng(1);
  int new_total = 0, placed_total = 0;
  for (long frame = 0; frame < 30; ++frame) {
    while (!rig.map->landmarks().empty()) rig.map->remove_landmark(*rig.map->landmarks().back());
    // Landmarks without a descriptor: the data manager predicts them (they occupy their cells) but cannot match them.
    std::vector<Eigen::Vector2d> projected;
    const int n = static_cast<int>(randu(rng, 0, 25));
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector2d z(randu(rng, 10, kWidth - 10), randu(rng, 10, kHeight - 10));
      slam::Landmark* l = rig.place(z, frame);
      ASSERT_NE(l, nullptr);
      ASSERT_TRUE(rig.visible(*l, opt.margin_px));
      ASSERT_LT((rig.obs(*l).h - z).norm(), 1e-6);
      projected.push_back(z);
    }
    placed_total += n;
    const int first_new = rig.map->landmarks().empty() ? 0 : rig.map->landmarks().back()->id() + 1;
    slam::FrameStats stats;
    dm.process(*rig.map, *rig.sensor, raw, frame, stats);
    const InitGrid& grid = dm.grid();
    std::set<int> used_cells;
    int news = 0;
    for (const auto& l : rig.map->landmarks()) {
      if (l->id() < first_new) continue;
      ++news;
      const PointDescriptor* d = point_descriptor(*l);
      ASSERT_NE(d, nullptr);
      // The cell the corner was detected in: its integer response maximum (the sub-pixel edge-line refinement can
      // move the landmark's pixel z0 a few pixels, across a cell boundary at times).
      const int cell = grid.cell_of(d->patch_centre_px);
      ASSERT_GE(cell, 0);
      EXPECT_TRUE(used_cells.insert(cell).second) << "frame " << frame << ": two new landmarks in cell " << cell;
      const Eigen::Vector4d r = grid.cell_rect(cell);
      EXPECT_TRUE(inside(r, d->patch_centre_px));
      for (const Eigen::Vector2d& z : projected) {
        EXPECT_FALSE(inside(r, z)) << "frame " << frame << ": new landmark " << l->id() << " at ("
                                   << d->patch_centre_px.transpose() << ") in a cell holding a landmark at ("
                                   << z.transpose() << ")";
      }
    }
    EXPECT_EQ(news, stats.initialized);
    new_total += news;
  }
  EXPECT_GT(new_total, 300);  // most empty cells got a landmark
  EXPECT_GT(placed_total, 200);
}

}  // namespace
}  // namespace rtslam::strategies
