// Evaluation of a run folder: files found, ATE/RPE/NEES/timing computed and written to eval.json.
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include "eval/eval_test_utils.hpp"
#include "eval/fake_run.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/eval/run_eval.hpp"
#include "support/temp_dir.hpp"

using namespace rtslam;
using namespace rtslam::eval;
namespace fs = std::filesystem;

namespace {
fs::path temp_dir(const std::string& name) { return ::rtslam::support::fresh_temp_dir("eval", name); }
}  // namespace

TEST(RunEval, ConsistentSimulatedRunHasSmallErrorAndNeesNearSix) {
  const fs::path dir = temp_dir("run");
  const int n = test::write_fake_run(dir.string(), {.seed = 3, .duration_s = 20.0});
  EvalOptions o;
  o.align = Alignment::Origin;
  const RunEvaluation r = evaluate_run(dir.string(), o);
  EXPECT_EQ(r.estimate_file, (dir / "trajectory.csv").string());
  EXPECT_EQ(r.metrics.n_matched, static_cast<std::size_t>(n));
  EXPECT_LT(r.metrics.ate.trans_m.rmse, 0.1);
  EXPECT_GT(r.metrics.ate.trans_m.rmse, 0.005);
  ASSERT_TRUE(r.nees_summary);
  EXPECT_NEAR(r.nees_summary->mean, 6.0, 0.8);  // 600 draws of χ²(6): ±0.14 (1σ)
  EXPECT_EQ(r.nees->skipped, 1u);
  EXPECT_EQ(r.timing.frames, static_cast<std::size_t>(n));
  EXPECT_GT(r.timing.median_ms, 8.0);
  const std::string path = write_run_eval(r);
  std::ifstream in(path);
  const auto j = nlohmann::json::parse(in);
  EXPECT_DOUBLE_EQ(j["ate"]["trans_m"]["rmse"].get<double>(), r.metrics.ate.trans_m.rmse);
  EXPECT_EQ(j["nees"]["values"].size(), r.nees->nees.size());
  fs::remove_all(dir);
}

TEST(RunEval, OverconfidentRunHasLargeNees) {
  const fs::path dir = temp_dir("overconfident");
  test::write_fake_run(dir.string(), {.seed = 4, .duration_s = 10.0, .rate_hz = 30.0, .cov_scale = 0.1});
  const RunEvaluation r = evaluate_run(dir.string(), {});
  ASSERT_TRUE(r.nees_summary);
  EXPECT_GT(r.nees_summary->mean, 40.0);
  fs::remove_all(dir);
}

TEST(RunEval, TumOnlyEstimateHasNoNeesButMetrics) {
  const fs::path dir = temp_dir("tum");
  test::write_fake_run(dir.string(), {.seed = 5, .duration_s = 5.0});
  fs::remove(dir / "trajectory.csv");
  fs::remove(dir / "frames.csv");
  const RunEvaluation r = evaluate_run(dir.string(), {});
  EXPECT_EQ(r.estimate_file, (dir / "trajectory.txt").string());
  EXPECT_FALSE(r.nees);
  EXPECT_NE(r.nees_note.find("no pose covariance"), std::string::npos);
  EXPECT_EQ(r.timing.frames, 0u);
  fs::remove_all(dir);
}

TEST(RunEval, MissingFilesAndBadCsvNameTheFile) {
  const fs::path dir = temp_dir("missing");
  try {
    evaluate_run(dir.string(), {});
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("trajectory.csv"), std::string::npos);
  }
  std::ofstream(dir / "bad.csv") << "t_s,time_total_ms\n1.0,2.0\n1.5,abc\n";
  try {
    read_csv_table((dir / "bad.csv").string());
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.csv:3"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

TEST(RunEval, ReadsTheFrameTableOfRtslamRun) {
  // `rtslam run` writes `#timestamp [ns],...,t_total [ms]`.
  const fs::path dir = temp_dir("frames");
  test::write_fake_run(dir.string(), {.seed = 6, .duration_s = 1.0});
  std::ofstream(dir / "frames.csv") << "#timestamp [ns],camera,landmarks,t_total [ms]\n0,0,10,0.5\n"
                                       "33333333,0,20,1.5\n66666666,0,20,2.5\n";
  const RunEvaluation r = evaluate_run(dir.string(), {});
  EXPECT_EQ(r.frame_time_ms, (std::vector<double>{0.5, 1.5, 2.5}));
  ASSERT_EQ(r.frame_t_s.size(), 3u);
  EXPECT_NEAR(r.frame_t_s[1], 0.033333333, 1e-12);
  EXPECT_DOUBLE_EQ(r.timing.median_ms, 1.5);
  fs::remove_all(dir);
}

TEST(Timing, PercentilesOfKnownList) {
  std::vector<double> ms;
  for (int i = 1; i <= 100; ++i) ms.push_back(i);
  const TimingStats s = compute_timing(ms);
  EXPECT_DOUBLE_EQ(s.mean_ms, 50.5);
  EXPECT_DOUBLE_EQ(s.median_ms, 50.5);
  EXPECT_DOUBLE_EQ(s.p95_ms, 95.0);
  EXPECT_DOUBLE_EQ(s.max_ms, 100.0);
}

// rtslam run's accuracy report: an estimate 5 % too large. With metric scale (inertial) the SE(3) ATE shows the
// error and the scale error says 5 %; a monocular run's Sim(3) ATE absorbs the scale.
TEST(RunAccuracy, MetricRunsReportSe3AteAndTheScaleErrorMonocularRunsSim3) {
  Trajectory gt = test::wavy_trajectory(400);
  Trajectory est = gt;
  for (auto& p : est.poses) p.p_WR *= 1.05;
  const eval::RunAccuracy metric = eval::evaluate_accuracy(est, gt, true);
  EXPECT_EQ(metric.options.align, eval::Alignment::Se3);
  EXPECT_NEAR(metric.scale_error, 1.0 - 1.0 / 1.05, 1e-9);
  EXPECT_GT(metric.ate.ate.trans_m.rmse, 0.01);
  EXPECT_NE(metric.line.find("scale error 4.76 %"), std::string::npos) << metric.line;
  const eval::RunAccuracy mono = eval::evaluate_accuracy(est, gt, false);
  EXPECT_EQ(mono.options.align, eval::Alignment::Sim3);
  EXPECT_LT(mono.ate.ate.trans_m.rmse, 1e-9);
  EXPECT_FALSE(mono.rpe_10m.has_value());
}
