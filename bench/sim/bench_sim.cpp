// Simulator micro-benchmarks: rendering one EuRoC-sized frame (budget: <= 45 ms median with 2x2 supersampling on
// 2 threads, so that `rtslam run` on the simulator keeps up with 20 Hz), the ray table, IMU synthesis. Run: build-<name>/bench/sim/bench_sim --benchmark_repetitions=5 --benchmark_report_aggregates_only
#include <benchmark/benchmark.h>

#include "rtslam/sim/imu.hpp"
#include "rtslam/sim/renderer.hpp"
#include "rtslam/sim/trajectory.hpp"
#include "rtslam/sim/world.hpp"

namespace {

using namespace rtslam;

models::PinholeCamera euroc_cam0() {
  models::CameraIntrinsics in;
  in.width = 752;
  in.height = 480;
  in.fx = 458.654;
  in.fy = 457.296;
  in.cx = 367.215;
  in.cy = 248.375;
  in.model = models::DistortionModel::RadTan;
  in.coeffs = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  return models::PinholeCamera(in);
}

sim::World& room() {
  static sim::World world(sim::WorldConfig::preset("room"));
  return world;
}

// Renders frames along the handheld trajectory; args: supersampling, threads, vectorized (1: the AVX2 paths when
// the CPU has them, 0: the plain ones; the same pixels).
void BM_RenderFrame(benchmark::State& state) {
  const models::PinholeCamera cam = euroc_cam0();
  sim::RenderOptions opt;
  opt.supersampling = static_cast<int>(state.range(0));
  opt.threads = static_cast<int>(state.range(1));
  room().set_vectorized(state.range(2) != 0);
  state.SetLabel(room().vectorized() ? "avx2" : "plain");
  const sim::Renderer renderer(room(), cam, opt);
  const auto traj = sim::make_handheld(1, Eigen::Vector3d(0, 0, 1.5), 60.0);
  Eigen::Matrix3d R_RS;  // EuRoC cam0 T_BS rotation (rounded): camera z ≈ body z
  R_RS << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  rtslam::TimeNs t = 0;
  std::uint64_t seed = 0;
  for (auto _ : state) {
    const sim::KinematicState s = traj->at(t);
    math::Pose T_WC;
    T_WC.q = s.q_WR * Eigen::Quaterniond(R_RS);
    T_WC.p = s.p_WR;
    benchmark::DoNotOptimize(renderer.render(T_WC, ++seed).data);
    t += 50'000'000;
  }
}
BENCHMARK(BM_RenderFrame)
    ->Args({2, 2, 1})
    ->Args({2, 2, 0})
    ->Args({2, 1, 1})
    ->Args({2, 1, 0})
    ->Args({1, 2, 1})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_RayTable(benchmark::State& state) {
  const models::PinholeCamera cam = euroc_cam0();
  sim::RenderOptions opt;
  for (auto _ : state) {
    const sim::Renderer renderer(room(), cam, opt);
    benchmark::DoNotOptimize(renderer.valid_rays());
  }
}
BENCHMARK(BM_RayTable)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ImuSample(benchmark::State& state) {
  const auto traj = sim::make_high_dynamic(1, Eigen::Vector3d(0, 0, 1.5), 45.0);
  sim::ImuSynthesizer imu(*traj, sim::ImuSynthOptions{}, Rng(1));
  rtslam::TimeNs t = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(imu.sample(t));
    t += 5'000'000;
    if (t > traj->t_end()) state.SkipWithError("trajectory exhausted");
  }
}
BENCHMARK(BM_ImuSample)->Iterations(5000);

}  // namespace
