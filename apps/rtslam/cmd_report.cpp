// rtslam report RUN_DIR|BATCH_DIR: a self-contained HTML page with the paper's figures (gnuplot, SVG inline).
#include <iostream>
#include <memory>

#include "commands.hpp"
#include "rtslam/eval/report.hpp"

namespace rtslam::cli {

namespace {
struct ReportArgs {
  std::string dir, out, align = "se3";
};
}  // namespace

void register_report(CLI::App& app) {
  auto a = std::make_shared<ReportArgs>();
  auto* sub = app.add_subcommand("report", "Write an HTML report with the paper's figures for a run or a batch");
  sub->add_option("DIR", a->dir, "run directory (trajectory + groundtruth) or batch directory")->required();
  sub->add_option("--out", a->out, "HTML file (default: DIR/report.html)");
  sub->add_option("--align", a->align, "alignment for a run report: se3, sim3, posyaw, origin or none")
      ->capture_default_str();
  sub->callback([a] {
    eval::ReportOptions o;
    o.output = a->out;
    o.eval.align = eval::parse_alignment(a->align);
    const std::string written = eval::write_report(a->dir, o);  // before "wrote": an error must not follow it
    std::cout << "wrote " << written << '\n';
  });
}

}  // namespace rtslam::cli
