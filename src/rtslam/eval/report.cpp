#include "rtslam/eval/report.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/eval/batch.hpp"
#include "rtslam/eval/chi2.hpp"
#include "rtslam/eval/plot.hpp"
#include "rtslam/eval/run_eval.hpp"
#include "rtslam/io/text.hpp"

namespace rtslam::eval {

namespace fs = std::filesystem;

namespace {

constexpr double kDeg = 180.0 / std::numbers::pi;
// Two-sided 99 % quantile of the standard normal (the paper's 2.57σ confidence area).
constexpr double kZ99 = 2.5758293035489004;

std::string html_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  if (!in) throw IoError(fmt::format("{}: cannot open", p.string()));
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The <svg> element of a gnuplot SVG file (without the XML prolog and DOCTYPE), for inlining.
std::string inline_svg(const fs::path& p) {
  const std::string s = read_text(p);
  const auto pos = s.find("<svg");
  if (pos == std::string::npos) throw IoError(fmt::format("{}: not an SVG file", p.string()));
  return s.substr(pos);
}

// Roll, pitch, yaw (ZYX Euler angles, degrees) of a rotation.
Eigen::Vector3d rpy_deg(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d R = q.normalized().toRotationMatrix();
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  const double pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  const double roll = std::atan2(R(2, 1), R(2, 2));
  return Eigen::Vector3d(roll, pitch, yaw) * kDeg;
}

// Unwraps an angle sequence in degrees (no ±360° jumps in plots).
void unwrap_deg(std::vector<double>& a) {
  for (std::size_t i = 1; i < a.size(); ++i) {
    while (a[i] - a[i - 1] > 180.0) a[i] -= 360.0;
    while (a[i] - a[i - 1] < -180.0) a[i] += 360.0;
  }
}

const char* kStyle =
    "body{font-family:'DejaVu Sans',Arial,sans-serif;margin:24px auto;max-width:1100px;color:#222}"
    "h1{font-size:1.5em}h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ccc}"
    "table{border-collapse:collapse;margin:8px 0}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}"
    "th{background:#eee}td:first-child,th:first-child{text-align:left}"
    "figure{margin:12px 0}figure svg{max-width:100%;height:auto}figcaption{font-size:.9em;color:#444}"
    "pre{background:#f6f6f6;padding:8px;overflow-x:auto}.note{color:#a33}";

struct Page {
  std::string title;
  std::string html;
  void h2(const std::string& t) { html += "<h2>" + html_escape(t) + "</h2>\n"; }
  void p(const std::string& t, const char* cls = nullptr) {
    html += cls ? fmt::format("<p class=\"{}\">{}</p>\n", cls, html_escape(t)) : "<p>" + html_escape(t) + "</p>\n";
  }
  void pre(const std::string& t) { html += "<pre>" + html_escape(t) + "</pre>\n"; }
  void figure(const fs::path& dir, const Figure& f) {
    html += "<figure id=\"" + f.name + "\">\n" + inline_svg(dir / (f.name + ".svg")) + "\n<figcaption>" +
            html_escape(f.caption) + " (PNG: report_files/" + f.name + ".png)</figcaption></figure>\n";
  }
  std::string str() const {
    return "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>" + html_escape(title) +
           "</title><style>" + kStyle + "</style></head><body>\n<h1>" + html_escape(title) + "</h1>\n" + html +
           "</body></html>\n";
  }
};

void write_page(const std::string& path, const Page& page) {
  std::ofstream out = io::open_for_writing(path);
  out << page.str();
  io::close_checked(out, path);
}

std::string fig_path(const std::string& dat) { return gp_quote(dat); }

// Time axis relative to the first ground-truth pose.
double t0_of(const RunEvaluation& r) { return r.gt.poses.empty() ? 0.0 : to_seconds(r.gt.poses.front().t); }

std::vector<Figure> run_figures(const RunEvaluation& r, const fs::path& dir, double confidence) {
  std::vector<Figure> figs;
  const double t0 = t0_of(r);
  // Trajectory data: t, est xyz, gt xyz, est rpy, gt rpy.
  std::vector<std::vector<double>> cols(13);
  for (std::size_t i = 0; i < r.gt.poses.size(); ++i) {
    const auto& e = r.est_aligned.poses[i];
    const auto& g = r.gt.poses[i];
    cols[0].push_back(to_seconds(g.t) - t0);
    for (int k = 0; k < 3; ++k) cols[1 + k].push_back(e.p_WR[k]);
    for (int k = 0; k < 3; ++k) cols[4 + k].push_back(g.p_WR[k]);
    const Eigen::Vector3d ae = rpy_deg(e.q_WR), ag = rpy_deg(g.q_WR);
    for (int k = 0; k < 3; ++k) cols[7 + k].push_back(ae[k]);
    for (int k = 0; k < 3; ++k) cols[10 + k].push_back(ag[k]);
  }
  for (int k = 7; k < 13; ++k) unwrap_deg(cols[k]);
  write_columns((dir / "trajectory.dat").string(), cols,
                "t_s est_x est_y est_z gt_x gt_y gt_z est_roll est_pitch est_yaw gt_roll gt_pitch gt_yaw (deg)");
  const std::string traj = fig_path("trajectory.dat");
  const std::string align = to_string(r.metrics.align);
  {
    Figure f{"position", "Estimated position (" + align + "-aligned) and ground truth per axis over time (paper Fig. 3/5)",
             "", 1000, 720};
    std::string& b = f.body;
    b += "reset\nset multiplot layout 3,1\nset grid\nset key top left\n";
    const char* axes[] = {"x", "y", "z"};
    for (int k = 0; k < 3; ++k) {
      if (k == 2) b += "set xlabel 't (s)'\n";
      b += fmt::format("set ylabel '{} (m)'\n", axes[k]);
      b += fmt::format("plot {0} using 1:{1} with lines lw 2 lc rgb '#222222' title 'ground truth', "
                       "{0} using 1:{2} with lines lw 1.5 lc rgb '#1f77b4' title 'estimate'\n",
                       traj, 5 + k, 2 + k);
    }
    figs.push_back(f);
  }
  {
    Figure f{"orientation", "Estimated orientation (roll, pitch, yaw, ZYX Euler angles) and ground truth over time", "",
             1000, 720};
    std::string& b = f.body;
    b += "reset\nset multiplot layout 3,1\nset grid\nset key top left\n";
    const char* axes[] = {"roll", "pitch", "yaw"};
    for (int k = 0; k < 3; ++k) {
      if (k == 2) b += "set xlabel 't (s)'\n";
      b += fmt::format("set ylabel '{} (deg)'\n", axes[k]);
      b += fmt::format("plot {0} using 1:{1} with lines lw 2 lc rgb '#222222' title 'ground truth', "
                       "{0} using 1:{2} with lines lw 1.5 lc rgb '#d62728' title 'estimate'\n",
                       traj, 11 + k, 8 + k);
    }
    figs.push_back(f);
  }
  {
    Figure f{"topview", "Top view (x-y) of the estimate (" + align + "-aligned) and the ground truth", "", 800, 700};
    f.body = "reset\nset grid\nset size ratio -1\nset xlabel 'x (m)'\nset ylabel 'y (m)'\nset key top left\n" +
             fmt::format("plot {0} using 5:6 with lines lw 2 lc rgb '#222222' title 'ground truth', "
                         "{0} using 2:3 with lines lw 1.5 lc rgb '#1f77b4' title 'estimate'\n",
                         traj);
    figs.push_back(f);
  }
  {
    std::vector<double> t;
    for (TimeNs ti : r.metrics.ate.t) t.push_back(to_seconds(ti) - t0);
    write_columns((dir / "ate.dat").string(), {t, r.metrics.ate.trans_err_m, r.metrics.ate.rot_err_deg},
                  "t_s trans_err_m rot_err_deg");
    Figure f{"ate", fmt::format("Absolute trajectory error over time ({} alignment): RMSE {:.4f} m, {:.3f} deg", align,
                                r.metrics.ate.trans_m.rmse, r.metrics.ate.rot_deg.rmse),
             "", 1000, 480};
    f.body = "reset\nset multiplot layout 2,1\nset grid\nset ylabel 'translation (m)'\n"
             "plot 'ate.dat' using 1:2 with lines lw 1.5 lc rgb '#1f77b4' notitle\n"
             "set xlabel 't (s)'\nset ylabel 'rotation (deg)'\n"
             "plot 'ate.dat' using 1:3 with lines lw 1.5 lc rgb '#d62728' notitle\n";
    figs.push_back(f);
  }
  if (r.nees) {
    const NeesSeries& s = *r.nees;
    std::vector<std::vector<double>> ec(13);
    for (std::size_t i = 0; i < s.t.size(); ++i) {
      ec[0].push_back(to_seconds(s.t[i]) - t0);
      for (int k = 0; k < 6; ++k) {
        const double unit = k < 3 ? 1.0 : kDeg;
        ec[1 + k].push_back(s.error[i][k] * unit);
        ec[7 + k].push_back(kZ99 * s.sigma[i][k] * unit);
      }
    }
    write_columns((dir / "errors.dat").string(), ec,
                  "t_s e_px e_py e_pz (m) e_thx e_thy e_thz (deg) then 2.57 sigma of each");
    const char* names[] = {"x", "y", "z", "θx", "θy", "θz"};
    for (int part = 0; part < 2; ++part) {
      Figure f{part == 0 ? "errors_position" : "errors_orientation",
               part == 0 ? "Position error (true − estimate, world frame, first-pose aligned) with the 99 % (±2.57σ) "
                           "confidence area of the filter (paper Fig. 4)"
                         : "Orientation error Log(q̂⁻¹ ⊗ q) (robot frame) with the 99 % (±2.57σ) confidence area "
                           "(paper Fig. 4)",
               "", 1000, 720};
      std::string& b = f.body;
      b += "reset\nset multiplot layout 3,1\nset grid\nset key top left\n";
      for (int k = 0; k < 3; ++k) {
        const int c = part * 3 + k;
        if (k == 2) b += "set xlabel 't (s)'\n";
        b += fmt::format("set ylabel 'e_{{{}}} ({})'\n", names[c], part == 0 ? "m" : "deg");
        b += fmt::format("plot 'errors.dat' using 1:(-${0}):(${0}) with filledcurves fc rgb '#c6dbef' "
                         "fs solid 0.8 title '±2.57σ', 'errors.dat' using 1:{1} with lines lw 1.5 lc rgb '#08519c' "
                         "title 'error'\n",
                         8 + c, 2 + c);
      }
      figs.push_back(f);
    }
    const auto [lo, hi] = nees_band(6, 1, confidence);
    write_columns((dir / "nees.dat").string(), {ec[0], s.nees}, "t_s nees");
    Figure f{"nees",
             fmt::format("6-DoF pose NEES over time with the one-run {:g} % χ²(6) band [{:.3f}, {:.2f}] (paper Fig. 6); "
                         "mean {:.2f}, {:.0f} % of poses inside",
                         100 * confidence, lo, hi, r.nees_summary->mean, 100 * r.nees_summary->fraction_in_band),
             "", 1000, 450};
    f.body = fmt::format(
        "reset\nset grid\nset logscale y\nset xlabel 't (s)'\nset ylabel 'NEES'\nset key top left\n"
        "plot 'nees.dat' using 1:2 with lines lw 1.5 lc rgb '#1f77b4' title 'NEES', "
        "{0} with lines dt 2 lw 1.5 lc rgb '#d62728' title 'χ² band', {1} with lines dt 2 lw 1.5 lc rgb '#d62728' "
        "notitle, 6 with lines dt 3 lc rgb '#555555' title 'dof = 6'\n",
        io::format_double(lo), io::format_double(hi));
    figs.push_back(f);
  }
  if (!r.frame_time_ms.empty()) {
    write_columns((dir / "timing.dat").string(), {r.frame_time_ms}, "time_total_ms");
    Figure f{"timing",
             fmt::format("Per-frame processing time: mean {:.2f} ms, median {:.2f} ms, p95 {:.2f} ms, max {:.2f} ms "
                         "({} frames)",
                         r.timing.mean_ms, r.timing.median_ms, r.timing.p95_ms, r.timing.max_ms, r.timing.frames),
             "", 900, 420};
    f.body = "reset\nset grid\nset style fill solid 0.6 border -1\nset xlabel 'time per frame (ms)'\n"
             "set ylabel 'frames'\nplot 'timing.dat' using 1 bins=40 with boxes lc rgb '#2ca02c' notitle\n";
    figs.push_back(f);
  }
  return figs;
}

std::string stats_row(const std::string& name, const ErrorStats& s) {
  return fmt::format("<tr><td>{}</td><td>{}</td><td>{:.6f}</td><td>{:.6f}</td><td>{:.6f}</td><td>{:.6f}</td>"
                     "<td>{:.6f}</td><td>{:.6f}</td></tr>\n",
                     html_escape(name), s.n, s.rmse, s.mean, s.median, s.std, s.min, s.max);
}

}  // namespace

bool is_batch_dir(const std::string& dir) { return fs::exists(fs::path(dir) / "batch_plan.json"); }

std::string write_report(const std::string& dir, const ReportOptions& options) {
  if (!fs::is_directory(dir)) throw IoError(fmt::format("{}: not a directory", dir));
  return is_batch_dir(dir) ? write_batch_report(dir, options) : write_run_report(dir, options);
}

std::string write_run_report(const std::string& run_dir, const ReportOptions& options) {
  gnuplot_executable();  // fail early and clearly
  const RunEvaluation r = evaluate_run(run_dir, options.eval);
  write_run_eval(r);
  const fs::path files = fs::path(run_dir) / "report_files";
  fs::create_directories(files);
  const auto figs = run_figures(r, files, options.confidence);
  render_figures(figs, files.string());

  Page page;
  page.title = "rtslam run report: " + fs::path(run_dir).filename().string();
  page.p("Estimate " + r.estimate_file + " against " + r.groundtruth_file + ".");
  page.html += "<table><tr><th>metric</th><th>n</th><th>rmse</th><th>mean</th><th>median</th><th>std</th><th>min</th>"
               "<th>max</th></tr>\n";
  page.html += stats_row("ATE translation (m)", r.metrics.ate.trans_m);
  page.html += stats_row("ATE rotation (deg)", r.metrics.ate.rot_deg);
  if (r.metrics.rpe) {
    page.html += stats_row(fmt::format("RPE translation (m) per {:g} {}", options.eval.rpe.delta,
                                       to_string(options.eval.rpe.unit)),
                           r.metrics.rpe->trans_m);
    page.html += stats_row("RPE rotation (deg)", r.metrics.rpe->rot_deg);
  }
  page.html += "</table>\n";
  page.p(fmt::format("Alignment {} (scale {:.6f}); Sim(3) scale estimate {:.6f}; {} matched poses over {}{:.2f} m.",
                     to_string(r.metrics.align), r.metrics.alignment.s, r.metrics.sim3_scale, r.metrics.n_matched,
                     std::isfinite(r.metrics.duration_s) ? fmt::format("{:.2f} s and ", r.metrics.duration_s) : "",
                     r.metrics.path_length_m));
  if (const std::string w = alignment_warning(r.metrics); !w.empty()) page.p(w, "note");
  if (r.nees_summary)
    page.p(fmt::format("NEES (first-pose aligned): mean {:.3f} (expected 6), {:.1f} % of poses inside the {:g} % band "
                       "[{:.3f}, {:.2f}].",
                       r.nees_summary->mean, 100 * r.nees_summary->fraction_in_band, 100 * options.confidence,
                       r.nees_summary->band_lo, r.nees_summary->band_hi));
  else
    page.p("No NEES: " + r.nees_note, "note");
  if (r.frame_time_ms.empty()) page.p("No per-frame timing (frames.csv with time_total_ms missing).", "note");
  for (const auto& f : figs) {
    page.h2(f.name);
    page.figure(files, f);
  }
  const std::string out = options.output.empty() ? (fs::path(run_dir) / "report.html").string() : options.output;
  write_page(out, page);
  return out;
}

std::string write_batch_report(const std::string& batch_dir, const ReportOptions& options) {
  gnuplot_executable();
  BatchOptions bo = load_batch_plan(batch_dir);
  bo.out_dir = batch_dir;
  const auto groups = aggregate_batch(bo);
  const fs::path files = fs::path(batch_dir) / "report_files";
  fs::create_directories(files);

  Page page;
  page.title = "rtslam batch report: " + fs::absolute(batch_dir).filename().string();
  page.p(fmt::format("{} dataset(s) × {} config(s) × {} seed(s); run durations {}; alignment {}.", bo.datasets.size(),
                     bo.configs.size(), bo.seeds.size(),
                     bo.duration_s > 0 ? fmt::format("{:g} s", bo.duration_s) : std::string("full"),
                     to_string(bo.eval.align)));
  page.html += "<table><tr><th>dataset</th><th>config</th><th>runs ok/all</th><th>ATE trans RMSE mean (m)</th>"
               "<th>median</th><th>std</th><th>ATE rot RMSE mean (deg)</th><th>RPE trans RMSE mean (m)</th>"
               "<th>avg NEES</th><th>in band</th><th>band</th><th>frame ms mean / p95</th></tr>\n";
  for (const auto& g : groups) {
    const bool nees = !g.nees.t.empty();
    const auto ate_cell = [&g](double v, int decimals) {  // a group with no evaluated run has no ATE
      return g.evaluated ? fmt::format("{:.{}f}", v, decimals) : std::string("-");
    };
    page.html += fmt::format(
        "<tr><td>{}</td><td>{}</td><td>{}/{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>"
        "<td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
        html_escape(g.dataset), html_escape(g.config), g.evaluated, g.runs, ate_cell(g.ate_trans_rmse.mean, 4),
        ate_cell(g.ate_trans_rmse.median, 4), ate_cell(g.ate_trans_rmse.std, 4), ate_cell(g.ate_rot_rmse.mean, 3),
        g.rpe_trans_rmse.n ? fmt::format("{:.4f}", g.rpe_trans_rmse.mean) : "-",
        nees ? fmt::format("{:.2f}", g.nees_summary.mean) : "-",
        nees ? fmt::format("{:.0f} %", 100 * g.nees_summary.fraction_in_band) : "-",
        nees ? fmt::format("[{:.2f}, {:.2f}] N={}", g.nees_summary.band_lo, g.nees_summary.band_hi,
                           g.nees_summary.n_runs)
             : "-",
        g.timing.frames ? fmt::format("{:.2f} / {:.2f}", g.timing.mean_ms, g.timing.p95_ms) : "-");
  }
  page.html += "</table>\n";
  page.p("Tables: batch.md, batch.csv, batch.json in the batch directory.");

  int gi = 0;
  for (const auto& g : groups) {
    const std::string tag = fmt::format("g{}", gi++);
    page.h2(g.dataset + " / " + g.config);
    if (g.evaluated == 0) {
      page.p("No evaluated run in this group.", "note");
      continue;
    }
    std::vector<Figure> figs;
    // Per-run data: aligned estimates (top view), NEES series, ATE RMSE per seed, all frame times.
    std::vector<double> seeds_idx, ate;
    std::vector<double> frame_ms;
    std::string topview = "reset\nset grid\nset size ratio -1\nset xlabel 'x (m)'\nset ylabel 'y (m)'\nset key top left\nplot ";
    std::string nees_runs;
    std::vector<RunEvaluation> evals;
    for (std::size_t k = 0; k < g.run_dirs.size(); ++k) {
      RunEvaluation r;
      try {
        r = evaluate_run(g.run_dirs[k], bo.eval);
      } catch (const Error&) {
        continue;
      }
      const double t0 = t0_of(r);
      const std::string dat = fmt::format("{}_run{}.dat", tag, k);
      std::vector<std::vector<double>> c(5);
      for (std::size_t i = 0; i < r.gt.poses.size(); ++i) {
        c[0].push_back(r.est_aligned.poses[i].p_WR.x());
        c[1].push_back(r.est_aligned.poses[i].p_WR.y());
        c[2].push_back(r.gt.poses[i].p_WR.x());
        c[3].push_back(r.gt.poses[i].p_WR.y());
        c[4].push_back(to_seconds(r.gt.poses[i].t) - t0);
      }
      write_columns((files / dat).string(), c, "est_x est_y gt_x gt_y t_s");
      // Each run has its own ground truth (a seed may redraw the simulated motion): draw every one.
      topview += fmt::format("'{0}' using 3:4 with lines lw 2 lc rgb '#60222222' {1}, "
                             "'{0}' using 1:2 with lines lw 1 lc rgb '#401f77b4' {2}, ",
                             dat, k == 0 ? "title 'ground truth'" : "notitle",
                             k == 0 ? "title 'estimates (aligned)'" : "notitle");
      if (r.nees) {
        const std::string nd = fmt::format("{}_nees{}.dat", tag, k);
        std::vector<double> t;
        for (TimeNs ti : r.nees->t) t.push_back(to_seconds(ti) - t0);
        write_columns((files / nd).string(), {t, r.nees->nees}, "t_s nees");
        nees_runs += fmt::format("'{}' using 1:2 with lines lw 0.6 lc rgb '#b0a0a0a0' {}, ", nd,
                                 nees_runs.empty() ? "title 'single runs'" : "notitle");
      }
      seeds_idx.push_back(static_cast<double>(k + 1));
      ate.push_back(r.metrics.ate.trans_m.rmse);
      frame_ms.insert(frame_ms.end(), r.frame_time_ms.begin(), r.frame_time_ms.end());
    }
    if (!ate.empty()) {
      topview.resize(topview.size() - 2);
      figs.push_back({tag + "_topview", "Top view of every run's aligned estimate and its ground truth", topview + "\n",
                      800, 700});
      write_columns((files / (tag + "_ate.dat")).string(), {seeds_idx, ate}, "run ate_rmse_m");
      figs.push_back({tag + "_ate", fmt::format("ATE translation RMSE of each run: mean {:.4f} m, median {:.4f} m, "
                                                "std {:.4f} m",
                                                g.ate_trans_rmse.mean, g.ate_trans_rmse.median, g.ate_trans_rmse.std),
                      fmt::format("reset\nset grid\nset style fill solid 0.6 border -1\nset boxwidth 0.7\n"
                                  "set xlabel 'run'\nset ylabel 'ATE RMSE (m)'\nset yrange [0:*]\n"
                                  "plot '{}_ate.dat' using 1:2 with boxes lc rgb '#1f77b4' notitle\n",
                                  tag),
                      900, 400});
    }
    if (!g.nees.t.empty()) {
      const double t0 = to_seconds(g.nees.t.front());
      std::vector<double> t;
      for (TimeNs ti : g.nees.t) t.push_back(to_seconds(ti) - t0);
      // NEES series were written relative to each run's first ground-truth pose; the average is plotted on the
      // same axis by using the first run's offset when available.
      write_columns((files / (tag + "_nees_avg.dat")).string(), {t, g.nees.mean, g.nees.lo, g.nees.hi},
                    "t_s average_nees band_lo band_hi");
      const auto [lo1, hi1] = nees_band(6, 1, bo.confidence);
      figs.push_back(
          {tag + "_nees",
           fmt::format("Average NEES over {} runs with the {:g} % band of the average of N runs [{:.2f}, {:.2f}] "
                       "(paper Fig. 6; one-run band [{:.3f}, {:.2f}] dotted); mean {:.2f}, {:.0f} % of the time inside",
                       g.nees_summary.n_runs, 100 * bo.confidence, g.nees_summary.band_lo, g.nees_summary.band_hi, lo1,
                       hi1, g.nees_summary.mean, 100 * g.nees_summary.fraction_in_band),
           fmt::format("reset\nset grid\nset logscale y\nset xlabel 't (s)'\nset ylabel 'NEES'\nset key top left\n"
                       "plot {0}'{1}_nees_avg.dat' using 1:3:4 with filledcurves fc rgb '#fdd0a2' fs solid 0.6 "
                       "title 'band (N runs)', '{1}_nees_avg.dat' using 1:2 with lines lw 2 lc rgb '#d94801' "
                       "title 'average NEES', {2} with lines dt 3 lc rgb '#555555' title 'one-run band', {3} with "
                       "lines dt 3 lc rgb '#555555' notitle, 6 with lines dt 2 lc rgb '#000000' title 'dof = 6'\n",
                       nees_runs, tag, io::format_double(lo1), io::format_double(hi1)),
           1000, 480});
    } else {
      page.p("No NEES in this group (no pose covariances).", "note");
    }
    if (!frame_ms.empty()) {
      write_columns((files / (tag + "_timing.dat")).string(), {frame_ms}, "time_total_ms");
      figs.push_back({tag + "_timing",
                      fmt::format("Per-frame processing time over all runs: mean {:.2f} ms, median {:.2f} ms, p95 "
                                  "{:.2f} ms ({} frames)",
                                  g.timing.mean_ms, g.timing.median_ms, g.timing.p95_ms, g.timing.frames),
                      fmt::format("reset\nset grid\nset style fill solid 0.6 border -1\nset xlabel 'time per frame "
                                  "(ms)'\nset ylabel 'frames'\nplot '{}_timing.dat' using 1 bins=40 with boxes lc rgb "
                                  "'#2ca02c' notitle\n",
                                  tag),
                      900, 400});
    }
    render_figures(figs, files.string());
    for (const auto& f : figs) page.figure(files, f);
  }
  const std::string out = options.output.empty() ? (fs::path(batch_dir) / "report.html").string() : options.output;
  write_page(out, page);
  return out;
}

}  // namespace rtslam::eval
