#pragma once
// Harris point detection inside a region of interest, as RT-SLAM does it (paper, "Image processing"):
//  - minimal derivative mask [-1 0 1]: Dx = I(u+1, v) - I(u-1, v), Dy = I(u, v+1) - I(u, v-1) (grey levels),
//    i.e. the central-difference gradient g = D / 2 in grey levels per pixel;
//  - a square constant window of `window_size` x `window_size` pixels centred on the candidate, whose sums of
//    Dx², Dy², DxDy come from integral images of the three products;
//  - the structure matrix normalized by the number of window pixels, M = (1 / n) Σ_window [gx² gxgy; gxgy gy²],
//    so that thresholds do not depend on the window size. Unit of M: (grey level / px)²;
//  - response: Harris det(M) - k tr(M)² in (grey level / px)^4, or the smallest eigenvalue λmin of M in
//    (grey level / px)² (sqrt(λmin) is the RMS gradient along the weakest direction);
//  - edges are rejected by the eigenvalue ratio λmax / λmin <= edge_ratio (RT-SLAM's HARRIS_EDDGE);
//  - only the single best candidate of the ROI is returned (no full-image thresholding, no non-maximum
//    suppression): the first maximum in raster order among candidates passing threshold and edge test, refined to
//    sub-pixel by a quadratic fit of the response over its 3x3 neighbourhood.
// Default thresholds were chosen on the real EuRoC (752x480) and MonoSLAM (320x240) frames: see docs/vision.md.
// Pixel convention: see image.hpp (column u, row v, centre of the top-left pixel at (0, 0)).
#include <cstdint>
#include <optional>
#include <vector>

#include "rtslam/core/yaml.hpp"
#include "rtslam/vision/image.hpp"

namespace rtslam::vision {

enum class HarrisResponse { harris, min_eigen };
/// Sub-pixel refinement: quadratic least-squares fit of the response around its maximum, or the least-squares
/// intersection of the edge lines of the window (Förstner; exact for ideal corners at any orientation).
enum class HarrisSubpixel { quadratic, edge_lines };

struct HarrisOptions {
  int window_size = 5;                           // odd, in [3, 181] (RT-SLAM HARRIS_CONV_SIZE)
  double k = 0.04;                               // Harris constant, in (0, 0.25)
  HarrisResponse response = HarrisResponse::harris;
  double harris_threshold = 1000.0;              // (grey/px)^4, used when response == harris
  double min_eigen_threshold = 25.0;             // (grey/px)^2, used when response == min_eigen
  double edge_ratio = 5.0;                       // max λmax / λmin (>= 1)
  int border_px = 8;                             // candidates stay this far from the image borders (>= 0)
  HarrisSubpixel subpixel = HarrisSubpixel::edge_lines;  // see docs/vision.md for why not the quadratic fit

  /// The threshold of the selected response type.
  double threshold() const { return response == HarrisResponse::harris ? harris_threshold : min_eigen_threshold; }
  /// Throws ConfigError naming the key, the value and the bound.
  /// `where` names the options in messages (their config section, e.g. "search/zncc", or the file and section).
  void validate(const std::string& where = "harris options") const;
  /// Reads keys window_size, k, response ("harris" | "min_eigen"), harris_threshold, min_eigen_threshold,
  /// edge_ratio, border_px, subpixel ("quadratic" | "edge_lines"); unknown keys are errors (map.finish()); validates.
  static HarrisOptions from_yaml(YamlMap& map);
  /// The keys of from_yaml with their values.
  YAML::Node to_yaml() const;
};

struct Corner {
  double u = 0.0;  // sub-pixel position (image coordinates)
  double v = 0.0;
  int u_px = 0;    // integer position of the response maximum
  int v_px = 0;
  double score = 0.0;  // response at the integer maximum, in the unit of the response type
};

/// Finds the best corner of a region. Holds reusable buffers (no allocation once they have grown): use one
/// detector per thread.
class HarrisDetector {
 public:
  explicit HarrisDetector(HarrisOptions options = {});

  const HarrisOptions& options() const { return options_; }

  /// The best corner whose pixel lies in `roi` (image coordinates), at least border_px from the image borders and
  /// far enough from them for its window and derivatives; nullopt if none passes the threshold and edge test.
  std::optional<Corner> best_corner(ImageView image, const Roi& roi);

  /// Response of a normalized structure matrix [a c; c b] for the selected type.
  double response(double a, double b, double c) const;
  /// True if λmax / λmin <= edge_ratio (and λmin > 0).
  bool passes_edge_test(double a, double b, double c) const;

 private:
  HarrisOptions options_;
  std::vector<std::uint32_t> table_;  // integral images of Dx², Dy², DxDy (modulo 2^32, see .cpp)
  std::vector<double> resp_;          // responses of one row of candidates
};

}  // namespace rtslam::vision
