// EKF engine costs at RT-SLAM map sizes: robot prediction, one landmark correction (m = 2), and a batched
// correction of k landmarks (m = 2k), over a state of n covariance rows (robot 12 + Euclidean landmarks).
// Run: build/bench/filter/bench_filter --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <vector>

#include <benchmark/benchmark.h>

#include "rtslam/core/random.hpp"
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
  const MatrixXd F = MatrixXd::Identity(12, 12);
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

}  // namespace
