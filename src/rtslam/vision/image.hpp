#pragma once
// Grey 8-bit images for the front end: a light non-owning view and an owning image.
//
// Pixel convention (used by every vision/ routine): pixel (u, v) is column u, row v; the CENTRE of the top-left
// pixel is (0, 0), so pixel (u, v) covers [u - 0.5, u + 0.5] x [v - 0.5, v + 0.5]. Sub-pixel positions use the same
// axes. Memory is row-major: the pixel (u, v) of a view is data[v * stride + u].
#include <cstdint>
#include <vector>

#include "rtslam/core/error.hpp"

namespace rtslam::vision {

/// An axis-aligned rectangle of pixels: columns [x, x + w), rows [y, y + h).
struct Roi {
  int x = 0;
  int y = 0;
  int w = 0;
  int h = 0;

  bool empty() const { return w <= 0 || h <= 0; }
  bool contains(int u, int v) const { return u >= x && u < x + w && v >= y && v < y + h; }
  /// The intersection of two rectangles (empty rectangles come back with w or h == 0).
  Roi intersect(const Roi& o) const {
    const int x0 = x > o.x ? x : o.x;
    const int y0 = y > o.y ? y : o.y;
    const int x1 = (x + w < o.x + o.w) ? x + w : o.x + o.w;
    const int y1 = (y + h < o.y + o.h) ? y + h : o.y + o.h;
    return Roi{x0, y0, x1 > x0 ? x1 - x0 : 0, y1 > y0 ? y1 - y0 : 0};
  }
  bool operator==(const Roi&) const = default;
};

/// Cell (cx, cy) of a cells_x × cells_y grid laid over a width × height image inside a border: integer bounds, the
/// cells tile the inner rectangle exactly.
inline Roi grid_cell(int width, int height, int border, int cells_x, int cells_y, int cx, int cy) {
  const int x0 = border + (width - 2 * border) * cx / cells_x;
  const int x1 = border + (width - 2 * border) * (cx + 1) / cells_x;
  const int y0 = border + (height - 2 * border) * cy / cells_y;
  const int y1 = border + (height - 2 * border) * (cy + 1) / cells_y;
  return Roi{x0, y0, x1 - x0, y1 - y0};
}

/// A read-only window on 8-bit grey pixels owned elsewhere (an Image, a camera buffer, a cv::Mat).
struct ImageView {
  const std::uint8_t* data = nullptr;
  int width = 0;
  int height = 0;
  int stride = 0;  // bytes between the starts of two rows (>= width)

  bool empty() const { return data == nullptr || width <= 0 || height <= 0; }
  Roi rect() const { return Roi{0, 0, width, height}; }
  const std::uint8_t* row(int v) const { return data + static_cast<std::ptrdiff_t>(v) * stride; }
  std::uint8_t at(int u, int v) const { return row(v)[u]; }
  /// The sub-view of columns [x, x + w) and rows [y, y + h); the rectangle must lie inside the view
  /// (checked: throws InvariantError, a caller bug). Sub-view pixel (0, 0) is this view's pixel (x, y).
  ImageView roi(int x, int y, int w, int h) const {
    RTSLAM_CHECK(x >= 0 && y >= 0 && w >= 0 && h >= 0 && x + w <= width && y + h <= height,
                 "ImageView::roi: rectangle outside the view");
    return ImageView{data + static_cast<std::ptrdiff_t>(y) * stride + x, w, h, stride};
  }
  ImageView roi(const Roi& r) const { return roi(r.x, r.y, r.w, r.h); }
};

/// A writable window (output of warps, renderers).
struct MutableImageView {
  std::uint8_t* data = nullptr;
  int width = 0;
  int height = 0;
  int stride = 0;

  std::uint8_t* row(int v) const { return data + static_cast<std::ptrdiff_t>(v) * stride; }
  std::uint8_t& at(int u, int v) const { return row(v)[u]; }
  ImageView view() const { return ImageView{data, width, height, stride}; }
  operator ImageView() const { return view(); }  // NOLINT: a writable view is also a readable one
};

/// An owning, contiguous (stride == width) 8-bit grey image.
class Image {
 public:
  Image() = default;
  Image(int width, int height, std::uint8_t fill = 0) { resize(width, height, fill); }
  /// A deep copy of a view.
  static Image copy_of(ImageView src) {
    Image img(src.width, src.height);
    for (int v = 0; v < src.height; ++v)
      for (int u = 0; u < src.width; ++u) img.pixels_[static_cast<std::size_t>(v) * src.width + u] = src.at(u, v);
    return img;
  }

  /// Resizes (keeping the allocation when it is large enough) and fills every pixel.
  void resize(int width, int height, std::uint8_t fill = 0) {
    RTSLAM_CHECK(width >= 0 && height >= 0, "Image::resize: negative size");
    width_ = width;
    height_ = height;
    pixels_.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), fill);
  }

  int width() const { return width_; }
  int height() const { return height_; }
  bool empty() const { return pixels_.empty(); }
  std::uint8_t* data() { return pixels_.data(); }
  const std::uint8_t* data() const { return pixels_.data(); }
  std::uint8_t& at(int u, int v) { return pixels_[static_cast<std::size_t>(v) * width_ + u]; }
  std::uint8_t at(int u, int v) const { return pixels_[static_cast<std::size_t>(v) * width_ + u]; }

  ImageView view() const { return ImageView{pixels_.data(), width_, height_, width_}; }
  MutableImageView mutable_view() { return MutableImageView{pixels_.data(), width_, height_, width_}; }
  ImageView roi(int x, int y, int w, int h) const { return view().roi(x, y, w, h); }
  operator ImageView() const { return view(); }  // NOLINT: an image is usable wherever a view is

 private:
  int width_ = 0;
  int height_ = 0;
  std::vector<std::uint8_t> pixels_;
};

}  // namespace rtslam::vision
