// Reports: gnuplot renders every figure to SVG and PNG, and the HTML page inlines the SVGs (self-contained).
#include <filesystem>
#include <fstream>
#include <regex>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include "eval/fake_run.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/eval/batch.hpp"
#include "rtslam/eval/process.hpp"
#include "rtslam/eval/report.hpp"
#include "support/temp_dir.hpp"

using namespace rtslam;
using namespace rtslam::eval;
namespace fs = std::filesystem;

namespace {

fs::path report_dir(const std::string& name) { return ::rtslam::support::fresh_temp_dir("report", name); }

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

std::size_t count(const std::string& s, const std::string& what) {
  std::size_t n = 0;
  for (auto pos = s.find(what); pos != std::string::npos; pos = s.find(what, pos + 1)) ++n;
  return n;
}

bool have_gnuplot() { return !find_in_path("gnuplot").empty(); }

}  // namespace

TEST(Report, RunReportInlinesEveryFigureAsSvgAndWritesPngs) {
  if (!have_gnuplot()) GTEST_SKIP() << "gnuplot not installed";
  const fs::path dir = report_dir("run");
  test::write_fake_run(dir.string(), {.seed = 1, .duration_s = 6.0});
  ReportOptions o;
  o.eval.align = Alignment::Origin;
  const std::string html_path = write_report(dir.string(), o);
  EXPECT_EQ(html_path, (dir / "report.html").string());
  const std::string html = slurp(html_path);
  const std::vector<std::string> figs{"position", "orientation", "topview", "ate", "errors_position",
                                      "errors_orientation", "nees", "timing"};
  EXPECT_EQ(count(html, "<svg"), figs.size());
  EXPECT_EQ(count(html, "</svg>"), figs.size());
  for (const auto& f : figs) {
    EXPECT_NE(html.find("<figure id=\"" + f + "\">"), std::string::npos) << f;
    EXPECT_GT(fs::file_size(dir / "report_files" / (f + ".png")), 5000u) << f;
  }
  // Self-contained: no external references to scripts, images or style sheets.
  EXPECT_EQ(html.find("<script src"), std::string::npos);
  EXPECT_EQ(html.find("<img"), std::string::npos);
  EXPECT_EQ(html.find("xlink:href=\"http"), std::string::npos);
  EXPECT_NE(html.find("χ²(6) band [0.676, 18.55]"), std::string::npos);
  fs::remove_all(dir);
}

TEST(Report, BatchReportShowsAggregateTableAndAverageNees) {
  if (!have_gnuplot()) GTEST_SKIP() << "gnuplot not installed";
  const fs::path dir = report_dir("batch");
  BatchOptions o;
  o.out_dir = dir.string();
  o.executable = "/nonexistent/rtslam";  // never run: the runs are written directly below
  o.seeds = {0, 1, 2, 3};
  o.eval.align = Alignment::Origin;
  for (const auto& r : plan_batch(o)) test::write_fake_run(r.dir, {.seed = static_cast<std::uint64_t>(r.seed), .duration_s = 5.0});
  const BatchOutcome out = run_batch(o, {});  // everything is already finished: nothing is spawned
  EXPECT_EQ(out.skipped, 4u);
  EXPECT_EQ(out.ran, 0u);
  const std::string html = slurp(write_report(dir.string(), {}));
  EXPECT_EQ(count(html, "<svg"), 4u);  // top view, ATE per run, average NEES, timing
  EXPECT_NE(html.find("N=4"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir / "report_files" / "g0_nees.png"));
  fs::remove_all(dir);
}

TEST(Report, MissingGnuplotGivesAClearError) {
  const fs::path dir = report_dir("nognuplot");
  test::write_fake_run(dir.string(), {.seed = 1, .duration_s = 2.0});
  ::setenv("RTSLAM_GNUPLOT", "/nonexistent/gnuplot", 1);
  try {
    write_report(dir.string(), {});
    ::unsetenv("RTSLAM_GNUPLOT");
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    ::unsetenv("RTSLAM_GNUPLOT");
    EXPECT_NE(std::string(e.what()).find("gnuplot"), std::string::npos);
  }
  fs::remove_all(dir);
}
