// EKF engine costs at RT-SLAM map sizes: robot prediction, one landmark correction (m = 2), and a batched
// correction of k landmarks (m = 2k), over a state of n covariance rows (robot 12 + Euclidean landmarks).
// Run: build/bench/filter/bench_filter --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <vector>

#include <Eigen/Geometry>
#include <benchmark/benchmark.h>

#include "rtslam/core/random.hpp"
#include "rtslam/filter/kernels.hpp"
#include "rtslam/filter/state.hpp"

namespace {

using rtslam::filter::BlockId;
using rtslam::filter::BlockLayout;
using rtslam::filter::State;
using Eigen::MatrixXd;
using Eigen::VectorXd;

struct Fixture {
  State state;
  BlockId robot;
  std::vector<BlockId> landmarks;
  explicit Fixture(int n_rows) : state(rtslam::filter::StateOptions{.tangent_capacity = n_rows + 16}) {
    rtslam::Rng rng(1);
    robot = *state.add_block(BlockLayout::euclidean(12), VectorXd::Zero(12), MatrixXd::Identity(12, 12));
    const int n_lmk = (n_rows - 12) / 3;
    for (int i = 0; i < n_lmk; ++i) {
      // Correlated with the robot, as real landmarks are.
      MatrixXd J = MatrixXd::Zero(3, 12);
      J.leftCols(3).setIdentity();
      const BlockId parents[1] = {robot};
      landmarks.push_back(*state.add_block(BlockLayout::euclidean(3), rtslam::randn_vec<3>(rng), parents, J,
                                           0.1 * MatrixXd::Identity(3, 3)));
    }
  }
};

void BM_PredictRobot(benchmark::State& st) {
  Fixture f(static_cast<int>(st.range(0)));
  // A constant-velocity robot's transition (tangent p θ v ω): p += v dt, θ through a rotation and ω; the v and ω
  // rows are unit rows (predict() skips them). F's eigenvalues have modulus 1: P grows only polynomially over the
  // iterations (no overflow to inf).
  MatrixXd F = MatrixXd::Identity(12, 12);
  rtslam::Rng rng(2);
  F.block(0, 6, 3, 3) = 0.05 * MatrixXd::Identity(3, 3);
  F.block(3, 3, 3, 3) = Eigen::AngleAxisd(0.01, Eigen::Vector3d(1.0, 2.0, 3.0).normalized()).toRotationMatrix();
  for (int i = 3; i < 6; ++i)
    for (int k = 9; k < 12; ++k) F(i, k) = 0.05 * rtslam::randn(rng);
  const MatrixXd Q = 1e-6 * MatrixXd::Identity(12, 12);
  for (auto _ : st) {
    f.state.predict(f.robot, F, Q);
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_PredictRobot)->Arg(100)->Arg(300)->Arg(500)->Unit(benchmark::kMicrosecond);

void BM_CorrectBatch(benchmark::State& st) {
  Fixture f(static_cast<int>(st.range(0)));
  const int k = static_cast<int>(st.range(1));
  std::vector<BlockId> blocks = {f.robot};
  for (int i = 0; i < k; ++i) blocks.push_back(f.landmarks[static_cast<size_t>(i)]);
  MatrixXd H = MatrixXd::Zero(2 * k, 12 + 3 * k);
  for (int i = 0; i < k; ++i) {
    H.block(2 * i, 0, 2, 6).setConstant(0.1);
    H.block(2 * i, 12 + 3 * i, 2, 3).setConstant(0.2);
    H(2 * i, 12 + 3 * i) = 1.0;
    H(2 * i + 1, 12 + 3 * i + 1) = 1.0;
  }
  const VectorXd y = VectorXd::Constant(2 * k, 1e-3);
  const MatrixXd R = 1e6 * MatrixXd::Identity(2 * k, 2 * k);  // weak: the state barely changes across iterations
  for (auto _ : st) {
    const auto res = f.state.correct(blocks, H, y, R);
    benchmark::DoNotOptimize(res);
  }
}
BENCHMARK(BM_CorrectBatch)
    ->Args({100, 1})
    ->Args({300, 1})
    ->Args({500, 1})
    ->Args({500, 8})
    ->Args({500, 25})
    ->Unit(benchmark::kMicrosecond);

// The covariance as a long run leaves it: a robot (18 rows) and its camera extrinsics (6), then landmarks
// initialized as inverse-depth points (7 rows), some removed and some reparametrized into Euclidean points (3 rows)
// in the holes the others left; about 500 active rows in some 30 runs, as in the high-dynamic sequence.
struct FragmentedFixture {
  State state;
  BlockId robot;
  std::vector<BlockId> landmarks;
  FragmentedFixture() : state(rtslam::filter::StateOptions{.tangent_capacity = 600}) {
    rtslam::Rng rng(7);
    robot = *state.add_block(BlockLayout::euclidean(24), VectorXd::Zero(24), MatrixXd::Identity(24, 24));
    const BlockId parents[1] = {robot};
    auto add = [&](int t) {
      MatrixXd J = 0.1 * MatrixXd::Ones(t, 24);
      J.leftCols(std::min(t, 24)).diagonal().setOnes();
      const auto id = state.add_block(BlockLayout::euclidean(t), VectorXd::Zero(t),
                                      parents, J, 0.1 * MatrixXd::Identity(t, t));
      if (id) landmarks.push_back(*id);
    };
    for (int step = 0; step < 3000; ++step) {
      if (state.tangent_used() + 7 <= 500) {
        add(7);
      } else {
        const auto k = std::uniform_int_distribution<size_t>(0, landmarks.size() - 1)(rng);
        const bool ahp = state.block(landmarks[k]).tangent_size() == 7;
        state.remove_block(landmarks[k]);
        landmarks.erase(landmarks.begin() + static_cast<std::ptrdiff_t>(k));
        if (ahp && std::uniform_int_distribution<int>(0, 2)(rng) > 0) add(3);
      }
    }
  }
};

// A batched correction of k landmarks of the fragmented state (robot pose columns + each landmark's own).
struct Batch {
  std::vector<BlockId> blocks;
  MatrixXd H;
  VectorXd y;
  MatrixXd R;
  Batch(const FragmentedFixture& f, int first, int k) {
    blocks = {f.robot};
    int cols = 24;
    for (int i = 0; i < k; ++i) {
      blocks.push_back(f.landmarks[static_cast<size_t>(first + 3 * i)]);
      cols += f.state.block(blocks.back()).tangent_size();
    }
    H = MatrixXd::Zero(2 * k, cols);
    int col = 24;
    for (int i = 0; i < k; ++i) {
      const int t = f.state.block(blocks[static_cast<size_t>(i + 1)]).tangent_size();
      H.block(2 * i, 0, 2, 6).setConstant(0.1);  // the robot pose's columns only, as a camera sees it
      H.block(2 * i, col, 2, t).setConstant(0.2);
      H(2 * i, col) = 1.0;
      H(2 * i + 1, col + 1) = 1.0;
      col += t;
    }
    y = VectorXd::Constant(2 * k, 1e-3);
    R = 1e6 * MatrixXd::Identity(2 * k, 2 * k);  // weak: the state barely changes across iterations
  }
};

// One correction of k landmarks, then the covariance brought up to date (as the next prediction does).
void BM_CorrectFragmented(benchmark::State& st) {
  const auto isa = rtslam::filter::set_kernel_isa(static_cast<rtslam::filter::KernelIsa>(st.range(1)));
  FragmentedFixture f;
  const Batch b(f, 0, static_cast<int>(st.range(0)));
  for (auto _ : st) {
    const auto res = f.state.correct(b.blocks, b.H, b.y, b.R);
    f.state.apply_pending();
    benchmark::DoNotOptimize(res);
  }
  st.counters["rows"] = f.state.tangent_used();
  st.counters["runs"] = static_cast<double>(f.state.active_runs().size());
  st.SetLabel(rtslam::filter::to_string(isa));
  rtslam::filter::set_kernel_isa(rtslam::filter::best_kernel_isa());
}
BENCHMARK(BM_CorrectFragmented)
    ->Args({1, 3})
    ->Args({22, 3})
    ->Args({1, 2})
    ->Args({22, 2})
    ->Args({1, 1})
    ->Args({22, 1})
    ->Args({1, 0})
    ->Args({22, 0})
    ->Unit(benchmark::kMicrosecond);

// The downdate kernel alone, P ← P − W Wᵀ over n = 496 active rows of a 600-row covariance, m = 50 (25 landmarks),
// per instruction set (range 1; clamped to what the CPU has, see the label). range 0: 0 = the rows consecutive,
// 1 = runs of 7 and 3 rows (AHP and Euclidean landmarks) separated by one-row holes, so that most tiles straddle
// a hole. `per_fma` is the time per multiply-add of the lower triangle (n(n + 1)/2 · m).
void BM_Downdate(benchmark::State& st) {
  namespace k = rtslam::filter::kernels;
  const auto isa = rtslam::filter::set_kernel_isa(static_cast<rtslam::filter::KernelIsa>(st.range(1)));
  constexpr int kCapacity = 600, kRows = 496, kM = 50;
  std::vector<int> rows;
  for (int r = 0, run = 0; static_cast<int>(rows.size()) < kRows; ++run) {
    const int length = st.range(0) == 0 ? kRows : (run % 2 == 0 ? 7 : 3);
    for (int i = 0; i < length && static_cast<int>(rows.size()) < kRows; ++i) rows.push_back(r++);
    ++r;  // a hole (unused when the rows are consecutive: one run)
  }
  std::vector<k::LaneGroup> groups;
  for (int g = 0; g < (kRows + k::kPanelRows - 1) / k::kPanelRows * 2; ++g) {
    k::LaneGroup lg;
    for (int lane = 0; lane < k::kGroupLanes && g * k::kGroupLanes + lane < kRows; ++lane) {
      const int i = g * k::kGroupLanes + lane;
      const auto row = static_cast<size_t>(i);
      if (lg.segments == 0 || rows[row - 1] != rows[row] - 1) lg.base[lg.segments++] = rows[row] - lane;
      lg.mask[lg.segments - 1] |= 1u << lane;
    }
    groups.push_back(lg);
  }
  rtslam::Rng rng(3);
  std::vector<double> W(static_cast<size_t>(k::packed_size(kRows, kM)), 0.0);
  for (int i = 0; i < kRows; ++i) {
    for (int c = 0; c < kM; ++c) {
      const auto at = static_cast<size_t>((i / k::kPanelRows * kM + c) * k::kPanelRows + i % k::kPanelRows);
      W[at] = 1e-3 * rtslam::randn(rng);
    }
  }
  MatrixXd P = MatrixXd::Identity(kCapacity, kCapacity);
  const k::ActiveRows active{rows.data(), groups.data(), kRows};
  for (auto _ : st) {
    k::downdate_mirrored(P.data(), P.outerStride(), active, W.data(), kM, kM);
    benchmark::ClobberMemory();
  }
  st.counters["per_fma"] = benchmark::Counter(kRows * (kRows + 1) / 2.0 * kM,
                                              benchmark::Counter::kIsIterationInvariantRate |
                                                  benchmark::Counter::kInvert);
  st.SetLabel(rtslam::filter::to_string(isa));
  rtslam::filter::set_kernel_isa(rtslam::filter::best_kernel_isa());
}
BENCHMARK(BM_Downdate)
    ->ArgsProduct({{0, 1}, {3, 2, 1, 0}})
    ->Unit(benchmark::kMicrosecond);

// The corrections of one image of the high-dynamic sequence: the one-point RANSAC support set (22 landmarks), three
// rounds of active search (one landmark each, its innovation covariance computed first), then the covariance brought
// up to date (as the next prediction does).
void BM_FrameCorrections(benchmark::State& st) {
  const auto isa = rtslam::filter::set_kernel_isa(static_cast<rtslam::filter::KernelIsa>(st.range(0)));
  FragmentedFixture f;
  const Batch ransac(f, 0, 22);
  const Batch r1(f, 1, 1), r2(f, 2, 1), r3(f, 4, 1);
  MatrixXd S(2, 2);
  for (auto _ : st) {
    auto res = f.state.correct(ransac.blocks, ransac.H, ransac.y, ransac.R);
    for (const Batch* r : {&r1, &r2, &r3}) {
      f.state.innovation_covariance(r->blocks, r->H, r->R, S);
      res = f.state.correct(r->blocks, r->H, r->y, r->R);
    }
    f.state.apply_pending();
    benchmark::DoNotOptimize(res);
  }
  st.SetLabel(rtslam::filter::to_string(isa));
  rtslam::filter::set_kernel_isa(rtslam::filter::best_kernel_isa());
}
BENCHMARK(BM_FrameCorrections)->Arg(3)->Arg(2)->Arg(1)->Arg(0)->Unit(benchmark::kMicrosecond);

}  // namespace

// The cost of one image's correction as the map grows (docs/performance.md): a batched correction of k landmarks
// (m = 2k rows) over a state of n covariance rows (robot 12 + Euclidean landmarks, every one correlated with the
// robot), then the covariance brought up to date (the deferred downdate, as the next prediction does). The dense
// work is the downdate P ← P − W Wᵀ, n²·m/2 multiply-adds on the lower triangle, and P Hᵀ (n·m·(6 + 3) reads):
// the counter `per_n2m` is the time divided by n²·m, flat when the O(n²·m) bound is what costs.
// Run: build/bench/filter/bench_filter --benchmark_filter=CostVsMapSize --benchmark_repetitions=3
//        --benchmark_report_aggregates_only=true
void BM_CostVsMapSize(benchmark::State& st) {
  const int n = static_cast<int>(st.range(0));
  const int k = static_cast<int>(st.range(1));
  Fixture f(n);
  std::vector<BlockId> blocks = {f.robot};
  for (int i = 0; i < k; ++i) blocks.push_back(f.landmarks[static_cast<size_t>(i)]);
  MatrixXd H = MatrixXd::Zero(2 * k, 12 + 3 * k);
  for (int i = 0; i < k; ++i) {
    H.block(2 * i, 0, 2, 6).setConstant(0.1);
    H(2 * i, 12 + 3 * i) = 1.0;
    H(2 * i + 1, 12 + 3 * i + 1) = 1.0;
    H(2 * i, 12 + 3 * i + 2) = 0.2;
  }
  const VectorXd y = VectorXd::Constant(2 * k, 1e-3);
  const MatrixXd R = 1e6 * MatrixXd::Identity(2 * k, 2 * k);  // weak: the state barely changes across iterations
  for (auto _ : st) {
    const auto res = f.state.correct(blocks, H, y, R);
    f.state.apply_pending();
    benchmark::DoNotOptimize(res);
  }
  const double n2m = static_cast<double>(f.state.tangent_used()) * f.state.tangent_used() * 2.0 * k;
  st.counters["rows"] = f.state.tangent_used();
  st.counters["m"] = 2.0 * k;
  st.counters["per_n2m"] = benchmark::Counter(n2m, benchmark::Counter::kIsIterationInvariantRate |
                                                        benchmark::Counter::kInvert);
}
BENCHMARK(BM_CostVsMapSize)
    ->Apply([](benchmark::internal::Benchmark* b) {
      for (int k : {1, 5, 12, 22}) {  // 22: the one-point RANSAC support set of a high-dynamic image
        for (int n = 50; n <= 500; n += 50) {
          if (k <= (n - 12) / 3) b->Args({n, k});
        }
      }
    })
    ->Unit(benchmark::kMicrosecond);
