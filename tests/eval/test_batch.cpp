// Batches: planning, parallel runs of independent processes, resuming, failure handling, aggregation, and the
// generated cluster command list / Slurm script. Uses eval_fake_run (fake_run.hpp) in place of `rtslam run`.
#include <filesystem>
#include <fstream>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include "rtslam/core/error.hpp"
#include "rtslam/eval/batch.hpp"
#include "rtslam/eval/process.hpp"
#include "support/temp_dir.hpp"

using namespace rtslam;
using namespace rtslam::eval;
namespace fs = std::filesystem;

namespace {

fs::path temp_dir(const std::string& name) { return ::rtslam::support::fresh_temp_dir("batch", name, false); }

BatchOptions fake_options(const fs::path& dir, int n_seeds) {
  BatchOptions o;
  o.out_dir = dir.string();
  o.executable = EVAL_FAKE_RUN;
  o.seeds.clear();
  for (int s = 0; s < n_seeds; ++s) o.seeds.push_back(s);
  o.duration_s = 4.0;
  o.jobs = 2;
  o.eval.align = Alignment::Origin;
  return o;
}

nlohmann::json read_json(const fs::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in);
}

}  // namespace

TEST(BatchPlan, BuildsTheMatrixWithOneFolderPerRun) {
  BatchOptions o = fake_options(temp_dir("plan"), 3);
  o.configs = {"default", "cfg/fast.yaml"};
  const auto runs = plan_batch(o);
  ASSERT_EQ(runs.size(), 6u);
  EXPECT_NE(runs[4].dir.find("runs/sim/fast/seed_0001"), std::string::npos) << runs[4].dir;
  const std::vector<std::string> head{EVAL_FAKE_RUN, "run", "--seed", "1", "--out", runs[4].dir, "--duration", "4"};
  EXPECT_EQ(std::vector<std::string>(runs[4].argv.begin(), runs[4].argv.begin() + 8), head);
  EXPECT_EQ(runs[4].argv[8], "--config");
  o.seeds = {1, 1};
  EXPECT_THROW(plan_batch(o), ConfigError);
  o.seeds = {1};
  o.configs = {"a/x.yaml", "b/x.yaml"};
  EXPECT_THROW(plan_batch(o), ConfigError);
}

TEST(Batch, RunsInParallelResumesAndAggregates) {
  const fs::path dir = temp_dir("run");
  BatchOptions o = fake_options(dir, 6);
  o.extra_args = {"--fail-seed", "4"};
  std::size_t max_running = 0;
  const BatchOutcome first = run_batch(o, [&](const BatchProgress& p) { max_running = std::max(max_running, p.running); });
  EXPECT_EQ(first.total, 6u);
  EXPECT_EQ(first.ran, 5u);
  EXPECT_EQ(first.failed, 1u);
  EXPECT_EQ(max_running, 2u);
  ASSERT_EQ(first.failed_dirs.size(), 1u);
  EXPECT_NE(first.failed_dirs[0].find("seed_0004"), std::string::npos);
  EXPECT_TRUE(fs::exists(fs::path(first.failed_dirs[0]) / "run.log"));
  EXPECT_TRUE(fs::exists(dir / "runs/sim/default/seed_0002/eval.json"));

  // Resume: the finished runs are not redone (their files keep their time stamps), the failed one is retried.
  const auto stamp = fs::last_write_time(dir / "runs/sim/default/seed_0002/trajectory.csv");
  o.extra_args.clear();
  const BatchOutcome second = run_batch(o, {});
  EXPECT_EQ(second.skipped, 5u);
  EXPECT_EQ(second.ran, 1u);
  EXPECT_EQ(second.failed, 0u);
  EXPECT_EQ(fs::last_write_time(dir / "runs/sim/default/seed_0002/trajectory.csv"), stamp);

  const auto groups = aggregate_batch(o);
  ASSERT_EQ(groups.size(), 1u);
  EXPECT_EQ(groups[0].evaluated, 6u);
  EXPECT_EQ(groups[0].nees_summary.n_runs, 6);
  EXPECT_NEAR(groups[0].nees_summary.mean, 6.0, 0.6);  // consistent fake filter
  EXPECT_GT(groups[0].ate_trans_rmse.mean, 0.0);
  EXPECT_EQ(groups[0].timing.frames, 6u * 121u);
  for (const char* f : {"batch.md", "batch.csv", "batch.json", "batch_plan.json", "commands.txt"})
    EXPECT_TRUE(fs::exists(dir / f)) << f;
  const auto j = read_json(dir / "batch.json");
  EXPECT_EQ(j["runs"].size(), 6u);
  EXPECT_EQ(j["groups"][0]["nees"]["average"].size(), 120u);
  std::ifstream csv(dir / "batch.csv");
  std::string header, row;
  std::getline(csv, header);
  std::getline(csv, row);
  EXPECT_EQ(row.rfind("sim,default,6,6,0,", 0), 0u) << row;
  // The plan reads back for later aggregation/reporting.
  const BatchOptions back = load_batch_plan(dir.string());
  EXPECT_EQ(back.seeds, o.seeds);
  EXPECT_EQ(back.eval.align, Alignment::Origin);
  fs::remove_all(dir);
}

TEST(Batch, AStoredEvaluationMadeWithOtherOptionsIsRedoneAndThePlanIsWrittenWhenAggregating) {
  // A batch aggregated again with another alignment used to keep each run's eval.json of the first (its table then
  // said "sim3" over SE(3)/origin numbers); an aggregation without a run (--aggregate-only after --emit-slurm) wrote no
  // batch_plan.json, so no report could be made; a metric no run has was a 0 in batch.csv.
  const fs::path dir = temp_dir("options");
  BatchOptions o = fake_options(dir, 2);
  ASSERT_EQ(run_batch(o, {}).failed, 0u);
  const auto origin = aggregate_batch(o);
  const fs::path eval_json = dir / "runs/sim/default/seed_0001/eval.json";
  EXPECT_EQ(read_json(eval_json)["options"]["align"], "origin");
  fs::remove(dir / "batch_plan.json");
  o.eval.align = Alignment::Sim3;
  o.eval.rpe.delta = 1000.0;  // metres: longer than the runs, so no run has an RPE
  o.eval.rpe.unit = DeltaUnit::Meters;
  o.eval.rpe.all_pairs = true;  // an option the plan's first keys did not hold
  const auto sim3 = aggregate_batch(o);
  ASSERT_EQ(sim3.size(), 1u);
  EXPECT_EQ(sim3[0].evaluated, 2u);
  EXPECT_EQ(read_json(eval_json)["options"]["align"], "sim3");
  EXPECT_LT(sim3[0].ate_trans_rmse.mean, origin[0].ate_trans_rmse.mean);  // Sim(3) fits best; origin fits one pose
  EXPECT_EQ(sim3[0].rpe_trans_rmse.n, 0u);
  const BatchOptions back = load_batch_plan(dir.string());
  EXPECT_EQ(back.eval.align, Alignment::Sim3);
  EXPECT_EQ(back.eval.rpe.unit, DeltaUnit::Meters);
  EXPECT_TRUE(back.eval.rpe.all_pairs);
  // An aggregation of another matrix (an --aggregate-only without the batch's seeds) keeps the stored plan.
  BatchOptions one_seed = o;
  one_seed.seeds = {0};
  aggregate_batch(one_seed);
  EXPECT_EQ(load_batch_plan(dir.string()).seeds, o.seeds);
  std::ifstream csv(dir / "batch.csv");
  std::string header, row;
  std::getline(csv, header);
  std::getline(csv, row);
  const auto field = [](const std::string& line, int k) {
    std::size_t a = 0;
    for (int i = 0; i < k; ++i) a = line.find(',', a) + 1;
    return line.substr(a, line.find(',', a) - a);
  };
  ASSERT_EQ(field(header, 10), "rpe_trans_rmse_mean_m");
  EXPECT_EQ(field(row, 10), "") << row;
  EXPECT_NE(field(row, 5), "") << row;
  fs::remove_all(dir);
}

TEST(Batch, CommandListAndSlurmScriptRunOneIndependentProcessPerLine) {
  const fs::path dir = temp_dir("cluster");
  const BatchOptions o = fake_options(dir, 3);
  fs::create_directories(dir);
  const std::string commands = write_command_list(o, (dir / "commands.txt").string());
  write_slurm_script(o, (dir / "job.sh").string(), commands);
  std::ifstream in(commands);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  ASSERT_EQ(lines.size(), 3u);
  // The Slurm script is valid bash and selects line SLURM_ARRAY_TASK_ID + 1.
  EXPECT_EQ(run_process({"bash", "-n", (dir / "job.sh").string()}, ""), 0);
  std::ifstream js(dir / "job.sh");
  const std::string script((std::istreambuf_iterator<char>(js)), std::istreambuf_iterator<char>());
  EXPECT_NE(script.find("#SBATCH --array=0-2"), std::string::npos);
  // Run task 1 as Slurm would (without Slurm): exactly the run of seed 1 appears.
  ASSERT_EQ(run_process({"env", "SLURM_ARRAY_TASK_ID=1", "bash", (dir / "job.sh").string()}, ""), 0);
  EXPECT_TRUE(fs::exists(dir / "runs/sim/default/seed_0001/summary.json"));
  EXPECT_FALSE(fs::exists(dir / "runs/sim/default/seed_0000"));
  // Each line is also runnable on its own (GNU parallel / ssh) and is a no-op once the run is finished.
  const auto stamp = fs::last_write_time(dir / "runs/sim/default/seed_0001/summary.json");
  ASSERT_EQ(run_process({"bash", "-c", lines[1]}, ""), 0);
  EXPECT_EQ(fs::last_write_time(dir / "runs/sim/default/seed_0001/summary.json"), stamp);
  ASSERT_EQ(run_process({"bash", "-c", lines[0]}, ""), 0);
  EXPECT_TRUE(fs::exists(dir / "runs/sim/default/seed_0000/summary.json"));
  fs::remove_all(dir);
}

TEST(Batch, ARunThatEndedBrokenIsFailedNotAggregatedAndRetried) {
  // Review 27 Nov: `rtslam run` exits 1 after writing every output when tracking ended lost or never started; its
  // summary says "complete", and the batch aggregated it and counted it resumed.
  const fs::path dir = temp_dir("broken");
  BatchOptions o = fake_options(dir, 3);
  ASSERT_EQ(run_batch(o, {}).failed, 0u);
  const fs::path lost = dir / "runs/sim/default/seed_0001/summary.json";
  const fs::path never = dir / "runs/sim/default/seed_0002/summary.json";
  std::ofstream(lost) << "{\"status\": \"complete\", \"health\": {\"final\": \"lost\", \"never_tracked\": false}}\n";
  std::ofstream(never) << "{\"status\": \"complete\", \"health\": {\"final\": \"ok\", \"never_tracked\": true}}\n";
  fs::remove(dir / "runs/sim/default/seed_0001/eval.json");
  fs::remove(dir / "runs/sim/default/seed_0002/eval.json");
  const auto groups = aggregate_batch(o);
  ASSERT_EQ(groups.size(), 1u);
  EXPECT_EQ(groups[0].evaluated, 1u);
  EXPECT_EQ(groups[0].failed, 2u);
  const BatchOutcome again = run_batch(o, {});  // both retried (the fake run then finishes them)
  EXPECT_EQ(again.skipped, 1u);
  EXPECT_EQ(again.ran, 2u);
  EXPECT_EQ(aggregate_batch(o)[0].evaluated, 3u);
  fs::remove_all(dir);
}

TEST(Batch, ProgressLineShowsCountsAndBar) {
  BatchProgress p;
  p.total = 20;
  p.done = 5;
  p.skipped = 5;
  p.running = 2;
  p.elapsed_s = 10.0;
  const std::string s = format_progress(p, 10);
  EXPECT_EQ(s.rfind("[#####.....]", 0), 0u) << s;
  EXPECT_NE(s.find("10/20"), std::string::npos) << s;
  EXPECT_NE(s.find("ETA 20 s"), std::string::npos) << s;
}

TEST(Batch, AMissingExecutableFailsEveryRunWithoutAborting) {
  const fs::path dir = temp_dir("noexe");
  BatchOptions o = fake_options(dir, 2);
  o.executable = (dir / "no-such-rtslam").string();
  const BatchOutcome r = run_batch(o, {});
  EXPECT_EQ(r.failed, 2u);
  EXPECT_EQ(r.ran, 0u);
  const auto groups = aggregate_batch(o);
  EXPECT_EQ(groups[0].evaluated, 0u);
  EXPECT_EQ(groups[0].failed, 2u);
  fs::remove_all(dir);
}
