#pragma once
// A fast path for the PNGs datasets are made of: 8-bit greyscale, not interlaced (EuRoC, TUM-VI, the simulator's
// writer). The chunks are checked (CRC-32 of every chunk, IHDR first, IDAT contiguous, IEND last), the image data
// inflated with libdeflate (Adler-32 checked) and the rows unfiltered as the PNG specification says, so the pixels
// are those libpng gives. Anything else — another colour type or depth, interlacing, transparency or colour-space
// chunks, or any damage — returns false, and the caller decodes with OpenCV, which then accepts or rejects the file
// with its own message. Measured in docs/performance.md: 1.4x (real EuRoC) to 2.4x (rendered) faster than libpng.
#include <cstddef>

#include <opencv2/core.hpp>

namespace rtslam::io {

/// Decodes `data` into `out` (CV_8UC1) when it is an undamaged 8-bit grey non-interlaced PNG of at most
/// `max_pixels` pixels; false otherwise (`out` then unspecified).
bool decode_png_grey8(const unsigned char* data, std::size_t size, std::size_t max_pixels, cv::Mat& out);

/// True when `data` starts as a PNG whose chunk sequence ends before its IEND chunk (a chunk running past the end of
/// the data, or no IEND): a truncated file, which any decoder refuses. Reads only the chunk headers.
bool png_truncated(const unsigned char* data, std::size_t size);

}  // namespace rtslam::io
