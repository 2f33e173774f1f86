#pragma once
// Integral images (summed-area tables) of intensities and squared intensities, over a whole image or a ROI.
//
// Exact integer arithmetic:
//  - the sum table is uint32: 255 * pixels, exact for images up to 16.8 Mpx (a 1280x1024 image peaks at 3.3e8);
//  - the squared-sum table is uint32 modulo 2^32 (unsigned wrap-around is well defined). The four-corner difference
//    of a rectangle is exact whenever its true sum is below 2^32, so for every rectangle of at most
//    kMaxExactSqPx = 66,051 pixels (65025 * 66051 < 2^32), whatever the image. sum_sq() is exact for ANY rectangle:
//    a larger one is split into bands of at most kMaxExactSqPx pixels whose exact sums are added in uint64 (a whole
//    1280x1024 frame, up to 8.5e10, takes 21 bands). Half the bytes of a uint64 table: the tables are
//    memory-bound, see docs/vision.md.
// Tables are (w + 1) x (h + 1) with a zero first row and column: S(x, y) = sum of pixels [0, x) x [0, y) of the ROI.
// Buffers are kept between calls (compute() allocates only when the ROI grows). Rows are built by SSE2 or AVX2
// kernels (simd.hpp), which give the same tables as the plain C++ one.
#include <cstdint>
#include <vector>

#include "rtslam/vision/image.hpp"

namespace rtslam::vision {

class IntegralImages {
 public:
  /// Largest rectangle (pixels) whose squared sum one modular four-corner difference gives exactly.
  static constexpr int kMaxExactSqPx = 66051;

  /// Computes the tables over `roi` (clipped to the image). With with_squares = false only the sum table is built.
  /// Grows the tables to hold an roi of up to n_pixels pixels without allocating in compute().
  void reserve(std::size_t n_pixels, bool with_squares = true);
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
  /// Sum of the squared pixels of the same rectangle (requires has_squares()); exact for any rectangle, one table
  /// difference up to kMaxExactSqPx pixels.
  std::uint64_t sum_sq(int x, int y, int w, int h) const {
    if (static_cast<std::int64_t>(w) * h > kMaxExactSqPx) return sum_sq_banded(x, y, w, h);
    return sq_rect(x, y, w, h);
  }

  /// Raw tables, row-major with stride() = roi().w + 1 entries per row. The squared-sum entries are modulo 2^32
  /// (see above): use them only through differences of rectangles of at most kMaxExactSqPx pixels.
  const std::uint32_t* sum_table() const { return sum_.data(); }
  const std::uint32_t* sq_table() const { return sq_.data(); }
  int stride() const { return stride_; }

 private:
  std::size_t index(int x, int y) const {
    return static_cast<std::size_t>(y - roi_.y) * static_cast<std::size_t>(stride_) +
           static_cast<std::size_t>(x - roi_.x);
  }
  // The modular four-corner difference: the exact squared sum of rectangles of at most kMaxExactSqPx pixels.
  std::uint32_t sq_rect(int x, int y, int w, int h) const {
    const std::uint32_t* r0 = &sq_[index(x, y)];
    const std::uint32_t* r1 = r0 + static_cast<std::ptrdiff_t>(h) * stride_;
    return r1[w] - r1[0] - r0[w] + r0[0];
  }
  std::uint64_t sum_sq_banded(int x, int y, int w, int h) const;

  Roi roi_;
  int stride_ = 0;
  bool has_squares_ = false;
  std::vector<std::uint32_t> sum_;
  std::vector<std::uint32_t> sq_;  // modulo 2^32
};

}  // namespace rtslam::vision
