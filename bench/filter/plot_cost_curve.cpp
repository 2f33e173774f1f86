// plot_cost_curve: the figure of one correction's cost against the map size (issue 16, docs/performance.md).
//
//   build/bench/filter/bench_filter --benchmark_filter=CostVsMapSize --benchmark_repetitions=3
//       --benchmark_report_aggregates_only=true --benchmark_out=cost.json --benchmark_out_format=json   (one line)
//   build/bench/filter/plot_cost_curve cost.json OUT_DIR
//
// Reads BM_CostVsMapSize's entries of a Google Benchmark JSON file (the medians when repetitions were run, else the
// single runs), fits t = c + a n² + b n² m + d n m² by least squares (n covariance rows, m measurement rows: a fixed
// cost per correction, one pass over the stored triangle, the O(n²m) downdate, and the gain's triangular solve
// W = P Hᵀ L⁻ᵀ, docs/performance.md), prints the table with the model's value and writes OUT_DIR/cost_vs_map_size.{dat,gp,svg,png} (gnuplot): CPU time against n, one
// curve per m, the fit dashed.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "rtslam/core/error.hpp"
#include "rtslam/eval/plot.hpp"

namespace {

using rtslam::DataError;
using rtslam::IoError;

struct Point {
  double n = 0.0, m = 0.0, us = 0.0;
};

double to_us(double t, const std::string& unit, const std::string& path) {
  if (unit == "ns") return t * 1e-3;
  if (unit == "us") return t;
  if (unit == "ms") return t * 1e3;
  if (unit == "s") return t * 1e6;
  throw DataError(fmt::format("{}: unknown time_unit '{}'", path, unit));
}

std::vector<Point> read_points(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw IoError(fmt::format("{}: cannot open the benchmark results", path));
  nlohmann::json j;
  try {
    in >> j;
  } catch (const nlohmann::json::exception& e) {
    throw DataError(fmt::format("{}: not a JSON file ({})", path, e.what()));
  }
  if (!j.contains("benchmarks") || !j["benchmarks"].is_array())
    throw DataError(fmt::format("{}: no 'benchmarks' array (write it with --benchmark_out_format=json)", path));
  std::vector<Point> medians, runs;
  for (const auto& b : j["benchmarks"]) {
    const std::string name = b.value("name", "");
    if (name.rfind("BM_CostVsMapSize/", 0) != 0) continue;
    if (!b.contains("rows") || !b.contains("m") || !b.contains("cpu_time"))
      throw DataError(fmt::format("{}: {} lacks rows, m or cpu_time", path, name));
    const Point p{b["rows"].get<double>(), b["m"].get<double>(),
                  to_us(b["cpu_time"].get<double>(), b.value("time_unit", "ns"), path)};
    const std::string run_type = b.value("run_type", "iteration");
    if (run_type == "aggregate") {
      if (b.value("aggregate_name", "") == "median") medians.push_back(p);
    } else {
      runs.push_back(p);
    }
  }
  std::vector<Point> points = medians.empty() ? runs : medians;
  if (points.size() < 2)
    throw DataError(fmt::format("{}: fewer than 2 BM_CostVsMapSize results (run bench_filter with "
                                "--benchmark_filter=CostVsMapSize)", path));
  for (const Point& p : points)
    if (!(p.n > 0.0 && p.m > 0.0 && std::isfinite(p.us) && p.us > 0.0))
      throw DataError(fmt::format("{}: a BM_CostVsMapSize result is not positive and finite", path));
  return points;
}

// The model's terms at (n, m): 1, n², n² m, n m².
Eigen::Vector4d terms(const Point& p) { return {1.0, p.n * p.n, p.n * p.n * p.m, p.n * p.m * p.m}; }

// Least squares of t = c + a n² + b n² m + d n m², weighted by 1/t² (relative errors: the small maps count as much).
Eigen::Vector4d fit(const std::vector<Point>& pts) {
  Eigen::Matrix4d N = Eigen::Matrix4d::Zero();
  Eigen::Vector4d r = Eigen::Vector4d::Zero();
  for (const Point& p : pts) {
    const Eigen::Vector4d x = terms(p);
    const double w = 1.0 / (p.us * p.us);
    N += w * x * x.transpose();
    r += w * p.us * x;
  }
  const Eigen::FullPivLU<Eigen::Matrix4d> lu(N);
  if (lu.rank() < 4)
    throw DataError("the results do not separate the model's four terms (too few values of n or m?)");
  return lu.solve(r);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: plot_cost_curve BENCH_JSON OUT_DIR\n";
    return 2;
  }
  try {
    const std::string path = argv[1], dir = argv[2];
    const std::vector<Point> pts = read_points(path);
    const Eigen::Vector4d coef = fit(pts);
    const double c = coef[0], a = coef[1], b = coef[2], d = coef[3];
    std::map<double, std::vector<Point>> by_m;
    for (const Point& p : pts) by_m[p.m].push_back(p);
    std::cout << fmt::format("t = c + a n² + b n² m + d n m²: c = {:.2f} µs, a = {:.3f} ns, b = {:.1f} ps, "
                             "d = {:.1f} ps ({} results)\n",
                             c, a * 1e3, b * 1e6, d * 1e6, pts.size());
    std::cout << "    n     m    time (µs)   model (µs)   per n²m (ps)\n";
    double worst = 0.0;
    std::vector<std::vector<double>> cols(4);  // n, m, measured, model
    for (const auto& [m, v] : by_m) {
      for (const Point& p : v) {
        const double model = coef.dot(terms(p));
        worst = std::max(worst, std::abs(model / p.us - 1.0));
        std::cout << fmt::format("{:5.0f} {:5.0f} {:12.1f} {:12.1f} {:14.0f}\n", p.n, p.m, p.us, model,
                                 p.us * 1e6 / (p.n * p.n * p.m));
        cols[0].push_back(p.n);
        cols[1].push_back(p.m);
        cols[2].push_back(p.us);
        cols[3].push_back(model);
      }
    }
    std::cout << fmt::format("largest model error: {:.1f} %\n", 100.0 * worst);
    std::filesystem::create_directories(dir);
    rtslam::eval::write_columns(dir + "/cost_vs_map_size.dat", cols, "n m measured_us model_us");
    std::string plots;
    for (const auto& [m, v] : by_m) {
      if (!plots.empty()) plots += ", ";
      plots += fmt::format(
          "'cost_vs_map_size.dat' using ($2=={0:g}?$1:1/0):3 with linespoints title 'm = {0:g}', "
          "{3:.6e} + {1:.6e}*x*x + {2:.6e}*x*x*{0:g} + {4:.6e}*x*{0:g}*{0:g} with lines dashtype 2 "
          "linecolor 'grey50' notitle",
          m, a, b, c, d);
    }
    rtslam::eval::Figure f;
    f.name = "cost_vs_map_size";
    f.caption = "One batched correction of m measurement rows and the covariance brought up to date, against the "
                "state's covariance rows n (CPU time; dashed: c + a n² + b n² m + d n m² fitted)";
    f.body = fmt::format(
        "set xlabel 'covariance rows n'\nset ylabel 'CPU time per correction (µs)'\nset key top left\n"
        "set grid\nset xrange [0:*]\nset yrange [0:*]\nset title 'EKF correction cost against map size "
        "(fit: {:.1f} µs + {:.3f} ns n² + {:.1f} ps n² m + {:.1f} ps n m²)'\nplot {}\n",
        c, a * 1e3, b * 1e6, d * 1e6, plots);
    rtslam::eval::render_figures({f}, dir);
    std::cout << "wrote " << dir << "/cost_vs_map_size.svg and .png\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "plot_cost_curve: " << e.what() << '\n';
    return 1;
  }
}
