// Acceptance (slow): `rtslam batch` of 20 seeds of the real `rtslam run` built-in 10 s simulated hand-held
// sequence on 2 cores, with its report opened in headless Chromium. About 1 min in Release on 2 free cores.
//   ctest --test-dir build -L slow -R test_eval_acceptance --output-on-failure
// Skipped while `rtslam run` cannot write a run folder.
#include <gtest/gtest.h>

#include "eval/cli_test_utils.hpp"

using namespace rtslam::eval;
using namespace rtslam::eval::test;

TEST(Acceptance, RealRunSimulatedHandheldBatchOfTwentySeedsWithReport) {
  const fs::path dir = temp_dir("real");
  const int probe = run_process({RTSLAM_CLI, "run", "--seed", "0", "--out", (dir / "probe").string(), "--duration", "1"},
                                (dir / "probe.log").string());
  if (probe != 0 || !fs::exists(dir / "probe" / "summary.json")) {
    fs::remove_all(dir);
    GTEST_SKIP() << "rtslam run does not write run folders yet (exit code " << probe << ")";
  }
  const fs::path out = dir / "batch";
  const int code = run_process({RTSLAM_CLI, "batch", "--out", out.string(), "--seeds", "20", "--duration", "10", "-j",
                                "2", "--align", "sim3", "--report"},
                               (dir / "batch.log").string());
  ASSERT_EQ(code, 0) << "see " << (dir / "batch.log");
  const auto j = read_json(out / "batch.json");
  EXPECT_EQ(j["groups"][0]["runs"], 20);
  EXPECT_EQ(j["groups"][0]["evaluated"], 20);
  EXPECT_GT(j["groups"][0]["timing"]["frames"].get<int>(), 20 * 190);  // 10 s at 20 Hz
  expect_screenshot_shows_figures(out / "report.html", dir);
  fs::remove_all(dir);
}
