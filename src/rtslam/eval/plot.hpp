#pragma once
// Figures drawn by gnuplot (Debian gnuplot-nox): each figure is a gnuplot script body rendered twice, to SVG (to
// embed in HTML) and to PNG (pngcairo). Data go through plain whitespace-separated .dat files next to the scripts.
#include <string>
#include <vector>

namespace rtslam::eval {

struct Figure {
  std::string name;     // file stem: DIR/name.gp, DIR/name.svg, DIR/name.png
  std::string caption;  // shown under the figure in reports
  std::string body;     // gnuplot commands after the terminal and output are set (may use multiplot)
  int width = 1000, height = 600;
};

/// The gnuplot binary: $RTSLAM_GNUPLOT if set, else `gnuplot` from PATH; throws IoError saying how to install it
/// when it is missing.
std::string gnuplot_executable();

/// Writes DIR/<name>.gp for every figure and runs gnuplot on it, producing DIR/<name>.svg and DIR/<name>.png.
/// Throws IoError naming the script and quoting gnuplot's message on failure.
void render_figures(const std::vector<Figure>& figures, const std::string& dir);

/// Writes columns of equal length as a whitespace-separated .dat file (NaN written as "NaN", which gnuplot skips).
void write_columns(const std::string& path, const std::vector<std::vector<double>>& columns,
                   const std::string& header = "");

/// A gnuplot string literal (single-quoted, quotes doubled).
std::string gp_quote(const std::string& s);

}  // namespace rtslam::eval
