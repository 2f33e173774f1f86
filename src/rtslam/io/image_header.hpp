#pragma once
// The size an encoded image declares, read from its header without decoding it, for the formats the dataset
// readers accept: PNG, PNM (PBM/PGM/PPM, P1-P6), JPEG, BMP and TIFF. decode_grey_image (source.hpp) refuses other
// formats and images beyond the limits below before a decoder allocates anything: a few corrupt header bytes must
// not make a reader allocate gigabytes (OpenCV's own limit is 1 Gpx, and some of its decoders allocate several
// times the image).
#include <cstddef>
#include <optional>
#include <string>

namespace rtslam::io {

/// Largest image the loaders and readers accept: each side at most kMaxImageSide px and at most kMaxImagePixels px
/// in all (33.5 Mpx, 8K UHD). A calibration or an image file that states more is an error.
constexpr int kMaxImageSide = 1 << 16;
constexpr long long kMaxImagePixels = 1LL << 25;

enum class ImageFormat { Png, Pnm, Jpeg, Bmp, Tiff };

struct ImageHeader {
  ImageFormat format = ImageFormat::Png;
  long long width = 0;   // px, > 0
  long long height = 0;  // px, > 0
  /// TIFF: pixels of the largest strip or tile the decoder buffers (OpenCV holds one at up to 8 bytes a pixel);
  /// bits per sample and samples per pixel (other formats: 0, 0, 0).
  long long tiff_block_pixels = 0;
  int tiff_bits_per_sample = 0;
  int tiff_samples_per_pixel = 0;
};

/// The header of an encoded image, or nullopt if the bytes are none of the accepted formats or their header is
/// truncated or states no size (zero width or height).
std::optional<ImageHeader> read_image_header(const unsigned char* data, std::size_t size);

/// Why an image with this header must not be decoded ("declares 70000x70000 px, more than ..."), or "" if it may.
std::string image_header_problem(const ImageHeader& header);

std::string to_string(ImageFormat format);

}  // namespace rtslam::io
