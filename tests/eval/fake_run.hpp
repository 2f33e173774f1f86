#pragma once
// A stand-in for `rtslam run` in the eval tests: writes a run folder with the files `rtslam run` writes
// (trajectory.txt, trajectory.csv with 6x6 covariances, groundtruth.txt, frames.csv, summary.json) for a simulated
// hand-held motion, with an estimate whose error is drawn from its own covariance (a consistent filter).
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <Eigen/Cholesky>

#include "eval/eval_test_utils.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/io/trajectory_io.hpp"

namespace rtslam::eval::test {

struct FakeRunOptions {
  std::uint64_t seed = 0;
  double duration_s = 10.0;
  double rate_hz = 30.0;
  double cov_scale = 1.0;  // < 1: the stored covariance is over-confident
};

/// Writes the run folder; returns the number of poses.
inline int write_fake_run(const std::string& dir, const FakeRunOptions& o) {
  namespace fs = std::filesystem;
  fs::create_directories(dir);
  Rng rng(o.seed * 7919 + 17);
  const int n = static_cast<int>(std::lround(o.duration_s * o.rate_hz)) + 1;
  const Trajectory gt = wavy_trajectory(n, o.rate_hz);
  Trajectory est = gt;
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  std::ofstream frames(fs::path(dir) / "frames.csv");
  frames << "t_s,landmarks,time_total_ms\n";
  for (int i = 0; i < n; ++i) {
    auto& p = est.poses[static_cast<std::size_t>(i)];
    if (i == 0) {
      p.cov = Mat6::Zero();  // the gauge pose
    } else {
      // Uncertainty growing with time, correlated position/orientation.
      const double g = 1.0 + 0.5 * i / o.rate_hz;
      Mat6 A = Mat6::Identity();
      A(0, 4) = 0.3;
      A(1, 3) = -0.3;
      Eigen::Matrix<double, 6, 1> s;
      s << 0.01, 0.01, 0.02, 0.002, 0.002, 0.004;
      const Mat6 P = g * s.asDiagonal() * A * A.transpose() * s.asDiagonal();
      const Eigen::Matrix<double, 6, 1> e = Mat6(P.llt().matrixL()) * randn_vec<6>(rng);
      p.p_WR = gt.poses[static_cast<std::size_t>(i)].p_WR - e.head<3>();
      p.q_WR = gt.poses[static_cast<std::size_t>(i)].q_WR * exp_q(e.tail<3>()).conjugate();
      p.cov = o.cov_scale * P;
    }
    frames << to_seconds(p.t) << ',' << 40 + (i % 7) << ',' << 8.0 + 4.0 * std::abs(randn(rng)) << '\n';
  }
  io::write_tum((fs::path(dir) / "groundtruth.txt").string(), gt);
  io::write_tum((fs::path(dir) / "trajectory.txt").string(), est);
  io::write_trajectory_csv((fs::path(dir) / "trajectory.csv").string(), est);
  std::ofstream(fs::path(dir) / "summary.json") << "{\"frames\": " << n << ", \"seed\": " << o.seed << "}\n";
  return n;
}

}  // namespace rtslam::eval::test
