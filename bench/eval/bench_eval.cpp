// Evaluation costs: association + alignment + ATE + RPE of a 145 s trajectory (EuRoC length: 2,900 estimated poses
// at 20 Hz against 29,000 ground-truth poses at 200 Hz), NEES of 2,900 poses, and a chi-square quantile.
#include <cmath>

#include <benchmark/benchmark.h>

#include "rtslam/core/random.hpp"
#include "rtslam/eval/chi2.hpp"
#include "rtslam/eval/metrics.hpp"
#include "rtslam/eval/nees.hpp"

namespace {

using namespace rtslam;
using namespace rtslam::eval;

Trajectory make_trajectory(int n, double rate_hz) {
  Trajectory traj;
  for (int i = 0; i < n; ++i) {
    const double t = i / rate_hz;
    StampedPose p;
    p.t = from_seconds(t);
    p.p_WR = Eigen::Vector3d(std::sin(0.3 * t), std::cos(0.2 * t), 0.1 * t);
    p.q_WR = Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * t, Eigen::Vector3d(0.1, 0.2, 1.0).normalized()));
    traj.poses.push_back(p);
  }
  return traj;
}

Trajectory noisy(const Trajectory& gt, int stride) {
  Rng rng(1);
  Trajectory est;
  for (std::size_t i = 0; i < gt.poses.size(); i += static_cast<std::size_t>(stride)) {
    StampedPose p = gt.poses[i];
    p.p_WR += randn_vec<3>(rng, 0.01);
    Eigen::Matrix<double, 6, 6> P = 1e-4 * Eigen::Matrix<double, 6, 6>::Identity();
    p.cov = P;
    est.poses.push_back(p);
  }
  return est;
}

void BM_EvaluateSe3Euroc(benchmark::State& state) {
  const Trajectory gt = make_trajectory(29000, 200.0);
  const Trajectory est = noisy(gt, 10);
  EvalOptions o;
  o.rpe.delta = 1.0;
  o.rpe.unit = DeltaUnit::Meters;
  for (auto _ : state) benchmark::DoNotOptimize(evaluate(est, gt, o).ate.trans_m.rmse);
}
BENCHMARK(BM_EvaluateSe3Euroc)->Unit(benchmark::kMillisecond);

void BM_Nees(benchmark::State& state) {
  const Trajectory gt = make_trajectory(2900, 20.0);
  const Trajectory est = noisy(gt, 1);
  for (auto _ : state) benchmark::DoNotOptimize(compute_nees(est, gt).nees.back());
}
BENCHMARK(BM_Nees)->Unit(benchmark::kMicrosecond);

void BM_Chi2Quantile600(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(chi2_quantile(0.995, 600.0));
}
BENCHMARK(BM_Chi2Quantile600)->Unit(benchmark::kMicrosecond);

}  // namespace
