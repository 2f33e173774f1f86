#pragma once
// Sub-pixel refinement of a sampled peak, shared by the Harris detector and the ZNCC matcher.
#include <algorithm>

namespace rtslam::vision {

/// Quadratic peak offset along one axis from three samples (left, centre, right), in [-0.5, 0.5] px; 0 if the
/// samples are not concave.
inline double parabola_offset(double rm, double r0, double rp) {
  const double curv = rm - 2.0 * r0 + rp;
  if (!(curv < 0.0)) return 0.0;
  return std::clamp(0.5 * (rm - rp) / curv, -0.5, 0.5);
}

}  // namespace rtslam::vision
