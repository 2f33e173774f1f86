#pragma once
// Integral images (summed-area tables) of intensities and squared intensities, over a whole image or a ROI.
//
// Exact integer arithmetic: the sum table is uint32 (max 255 * pixels, exact for images up to 16.8 Mpx) and the
// squared-sum table is uint64 (max 65025 * pixels); a 1280x1024 image peaks at 3.3e8 and 8.5e10 — no overflow.
// Tables are (w + 1) x (h + 1) with a zero first row and column: S(x, y) = sum of pixels [0, x) x [0, y) of the ROI.
// Buffers are kept between calls (compute() allocates only when the ROI grows).
#include <cstdint>
#include <vector>

#include "rtslam/vision/image.hpp"

namespace rtslam::vision {

class IntegralImages {
 public:
  /// Computes the tables over `roi` (clipped to the image). With with_squares = false only the sum table is built.
  void compute(ImageView image, Roi roi, bool with_squares = true);
  /// Over the whole image.
  void compute(ImageView image, bool with_squares = true) { compute(image, image.rect(), with_squares); }

  /// The rectangle (image coordinates) the tables cover.
  const Roi& roi() const { return roi_; }
  bool has_squares() const { return has_squares_; }

  /// Sum of the pixels of columns [x, x + w), rows [y, y + h), in IMAGE coordinates; the rectangle must lie inside
  /// roi() (not checked: hot path).
  std::uint32_t sum(int x, int y, int w, int h) const {
    const std::uint32_t* r0 = &sum_[index(x, y)];
    const std::uint32_t* r1 = r0 + static_cast<std::ptrdiff_t>(h) * stride_;
    return r1[w] - r1[0] - r0[w] + r0[0];
  }
  /// Sum of the squared pixels of the same rectangle (requires has_squares()).
  std::uint64_t sum_sq(int x, int y, int w, int h) const {
    const std::uint64_t* r0 = &sq_[index(x, y)];
    const std::uint64_t* r1 = r0 + static_cast<std::ptrdiff_t>(h) * stride_;
    return r1[w] - r1[0] - r0[w] + r0[0];
  }

  /// Raw tables, row-major with stride() = roi().w + 1 entries per row.
  const std::uint32_t* sum_table() const { return sum_.data(); }
  const std::uint64_t* sq_table() const { return sq_.data(); }
  int stride() const { return stride_; }

 private:
  std::size_t index(int x, int y) const {
    return static_cast<std::size_t>(y - roi_.y) * static_cast<std::size_t>(stride_) +
           static_cast<std::size_t>(x - roi_.x);
  }

  Roi roi_;
  int stride_ = 0;
  bool has_squares_ = false;
  std::vector<std::uint32_t> sum_;
  std::vector<std::uint64_t> sq_;
};

}  // namespace rtslam::vision
