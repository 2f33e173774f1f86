// End-to-end through the rtslam CLI: `rtslam eval` on trajectory files, `rtslam batch` of 20 seeds of 10 s on
// 2 cores with its report, opened in headless Chromium (screenshot must show the figures). `rtslam batch` drives
// eval_fake_run here, and the real `rtslam run` too once it writes run folders (skipped until then).
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "eval/cli_test_utils.hpp"
#include "eval/fake_run.hpp"
#include "rtslam/eval/metrics.hpp"
#include "rtslam/eval/process.hpp"
#include "rtslam/io/trajectory_io.hpp"

using namespace rtslam;
using namespace rtslam::eval;
using namespace rtslam::eval::test;
namespace fs = std::filesystem;


TEST(CliEval, PrintsTableAndWritesJsonEqualToTheLibrary) {
  const fs::path dir = temp_dir("eval");
  test::write_fake_run(dir.string(), {.seed = 2, .duration_s = 10.0});
  const fs::path json = dir / "out.json";
  const int code = run_process({RTSLAM_CLI, "eval", (dir / "trajectory.csv").string(), (dir / "groundtruth.txt").string(),
                                "--align", "sim3", "--delta", "1", "--delta-unit", "m", "--json", json.string()},
                               (dir / "eval.log").string());
  ASSERT_EQ(code, 0);
  const auto j = read_json(json);
  EvalOptions o;
  o.align = Alignment::Sim3;
  o.rpe.delta = 1.0;
  o.rpe.unit = DeltaUnit::Meters;
  const EvalResult r = evaluate(io::read_trajectory((dir / "trajectory.csv").string()),
                                io::read_trajectory((dir / "groundtruth.txt").string()), o);
  EXPECT_DOUBLE_EQ(j["ate"]["trans_m"]["rmse"].get<double>(), r.ate.trans_m.rmse);
  EXPECT_DOUBLE_EQ(j["rpe"]["trans_m"]["rmse"].get<double>(), r.rpe->trans_m.rmse);
  EXPECT_EQ(j["rpe"]["delta_unit"], "m");
  EXPECT_NEAR(j["nees"]["mean"].get<double>(), 6.0, 1.5);
  std::ifstream log(dir / "eval.log");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("ATE trans (m)"), std::string::npos) << text;
  // A bad option value fails with one clear line.
  EXPECT_NE(run_process({RTSLAM_CLI, "eval", (dir / "trajectory.txt").string(), (dir / "groundtruth.txt").string(),
                         "--align", "se2"},
                        (dir / "bad.log").string()),
            0);
  fs::remove_all(dir);
}

TEST(CliEval, CovariancesWithoutANeesStillGiveTheAccuracyAndItsJson) {
  // Covariances none of which is positive definite (all zero) give no NEES: a note, exit 0, the JSON written (the
  // ATE/RPE table was printed and then the command failed, without JSON).
  const fs::path dir = temp_dir("eval_zero_cov");
  test::write_fake_run(dir.string(), {.seed = 3, .duration_s = 4.0});
  Trajectory est = io::read_trajectory((dir / "trajectory.csv").string());
  for (StampedPose& p : est.poses) p.cov = Eigen::Matrix<double, 6, 6>::Zero();
  io::write_trajectory_csv((dir / "zero_cov.csv").string(), est);
  const fs::path json = dir / "out.json";
  const int code = run_process({RTSLAM_CLI, "eval", (dir / "zero_cov.csv").string(),
                                (dir / "groundtruth.txt").string(), "--json", json.string()},
                               (dir / "eval.log").string());
  std::ifstream log(dir / "eval.log");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  ASSERT_EQ(code, 0) << text;
  EXPECT_NE(text.find("NEES: none ("), std::string::npos) << text;
  const auto j = read_json(json);
  EXPECT_GT(j["ate"]["trans_m"]["rmse"].get<double>(), 0.0);
  EXPECT_TRUE(j["nees"].contains("note"));
  fs::remove_all(dir);
}

TEST(CliBatch, AFailedRunMakesTheBatchExitNonZeroAfterItsAggregates) {
  // Review 27 Nov: `rtslam batch` printed "1 failed" and exited 0.
  const fs::path dir = temp_dir("batch_fail");
  const fs::path out = dir / "batch";
  const fs::path log = dir / "batch.log";
  const int code = run_process({RTSLAM_CLI, "batch", "--out", out.string(), "--exe", EVAL_FAKE_RUN, "--seeds", "3",
                                "--duration", "2", "-j", "1", "--align", "origin", "--run-arg=--fail-seed",
                                "--run-arg=1"},
                               log.string());
  EXPECT_EQ(code, 1) << "see " << log;
  std::ifstream in(log);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("1 of the batch's runs failed"), std::string::npos) << text;
  const auto j = read_json(out / "batch.json");  // the aggregates of the others are still written
  EXPECT_EQ(j["groups"][0]["evaluated"], 2);
  fs::remove_all(dir);
}

TEST(CliBatch, TwentySeedsOfTenSecondsOnTwoCoresWithReportInChromium) {
  const fs::path dir = temp_dir("batch");
  const fs::path out = dir / "batch";
  const int code = run_process({RTSLAM_CLI, "batch", "--out", out.string(), "--exe", EVAL_FAKE_RUN, "--seeds", "20",
                                "--duration", "10", "-j", "2", "--align", "origin", "--report"},
                               (dir / "batch.log").string());
  ASSERT_EQ(code, 0) << "see " << (dir / "batch.log");
  const auto j = read_json(out / "batch.json");
  EXPECT_EQ(j["groups"][0]["evaluated"], 20);
  EXPECT_EQ(j["groups"][0]["nees"]["runs"], 20);
  ASSERT_TRUE(fs::exists(out / "report.html"));
  expect_screenshot_shows_figures(out / "report.html", dir);
  fs::remove_all(dir);
}
