#include "rtslam/io/image_header.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <vector>

#include <fmt/format.h>

namespace rtslam::io {
namespace {

/// Bounds-checked reads of big/little-endian integers; false past the end.
struct Bytes {
  const unsigned char* data;
  std::size_t size;
  bool big_endian = false;

  bool has(std::size_t pos, std::size_t n) const { return pos <= size && n <= size - pos; }
  bool u16(std::size_t pos, std::uint32_t& v) const {
    if (!has(pos, 2)) return false;
    v = big_endian ? (data[pos] << 8 | data[pos + 1]) : (data[pos + 1] << 8 | data[pos]);
    return true;
  }
  bool u32(std::size_t pos, std::uint32_t& v) const {
    if (!has(pos, 4)) return false;
    const std::uint32_t b0 = data[pos], b1 = data[pos + 1], b2 = data[pos + 2], b3 = data[pos + 3];
    v = big_endian ? (b0 << 24 | b1 << 16 | b2 << 8 | b3) : (b3 << 24 | b2 << 16 | b1 << 8 | b0);
    return true;
  }
};

std::optional<ImageHeader> sized(ImageFormat format, long long width, long long height) {
  if (width <= 0 || height <= 0) return std::nullopt;
  ImageHeader h;
  h.format = format;
  h.width = width;
  h.height = height;
  return h;
}

std::optional<ImageHeader> png(const Bytes& b) {
  // Signature (8), then the IHDR chunk: length (4), "IHDR", width and height (4 each, big-endian).
  std::uint32_t w = 0, h = 0;
  if (!b.has(12, 4) || std::memcmp(b.data + 12, "IHDR", 4) != 0 || !b.u32(16, w) || !b.u32(20, h)) return {};
  return sized(ImageFormat::Png, w, h);
}

std::optional<ImageHeader> pnm(const Bytes& b) {
  // "P1".."P6", then width and height as decimal text separated by white space and '#' comments, read as OpenCV's
  // ReadNumber does: the byte that ends a number is consumed with it, so in "33313#23332\n3" the '#' starts no
  // comment and the height is 23332 (reading 3 here let a 777 MB PBM through).
  std::size_t pos = 2;
  long long dims[2] = {0, 0};
  for (long long& d : dims) {
    while (pos < b.size) {
      const char c = static_cast<char>(b.data[pos]);
      if (c == '#') {
        while (pos < b.size && b.data[pos] != '\n' && b.data[pos] != '\r') ++pos;
      } else if (c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f') {
        ++pos;
      } else {
        break;
      }
    }
    int digits = 0;
    while (pos < b.size && b.data[pos] >= '0' && b.data[pos] <= '9') {
      if (++digits > 12) return {};
      d = d * 10 + (b.data[pos++] - '0');
    }
    if (digits == 0) return {};
    ++pos;  // the byte after the digits
  }
  return sized(ImageFormat::Pnm, dims[0], dims[1]);
}

std::optional<ImageHeader> jpeg(const Bytes& b) {
  // Segments after SOI: 0xFF, marker, then (except for RSTn/TEM) a 2-byte length. A start-of-frame segment
  // (SOF0-3, 5-7, 9-11, 13-15) holds precision (1), height (2), width (2).
  Bytes be = b;
  be.big_endian = true;
  std::size_t pos = 2;
  while (be.has(pos, 2)) {
    if (be.data[pos] != 0xFF) return {};
    const unsigned marker = be.data[pos + 1];
    if (marker == 0xFF) {  // fill byte
      ++pos;
      continue;
    }
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD7)) {
      pos += 2;
      continue;
    }
    if (marker == 0xD8 || marker == 0xD9 || marker == 0xDA) return {};  // SOI again, EOI or scan before a frame
    std::uint32_t length = 0;
    if (!be.u16(pos + 2, length) || length < 2) return {};
    const bool sof = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (sof) {
      std::uint32_t h = 0, w = 0;
      if (!be.u16(pos + 5, h) || !be.u16(pos + 7, w)) return {};
      return sized(ImageFormat::Jpeg, w, h);
    }
    pos += 2 + length;
  }
  return {};
}

std::optional<ImageHeader> bmp(const Bytes& b) {
  // File header (14), then the DIB header: its size (4); OS/2 v1 (12 bytes) has 16-bit width/height, the others
  // 32-bit signed ones (a negative height is a top-down image).
  std::uint32_t dib = 0;
  if (!b.u32(14, dib)) return {};
  std::uint32_t w = 0, h = 0;
  if (dib == 12) {
    if (!b.u16(18, w) || !b.u16(20, h)) return {};
    return sized(ImageFormat::Bmp, w, h);
  }
  if (dib < 16 || !b.u32(18, w) || !b.u32(22, h)) return {};
  const long long height = static_cast<std::int32_t>(h);
  return sized(ImageFormat::Bmp, static_cast<std::int32_t>(w), height < 0 ? -height : height);
}

std::optional<ImageHeader> tiff(Bytes b) {
  // Byte order (2), 42 (2), offset of the first image file directory (4). IFD: entry count (2), then 12-byte
  // entries: tag (2), type (2), count (4), value or offset (4). OpenCV decodes the first directory. A tag may be
  // there twice (which one libtiff keeps is its business): every value is checked, the largest counts.
  b.big_endian = b.data[0] == 'M';
  std::uint32_t ifd = 0, n = 0;
  if (!b.u32(4, ifd) || !b.u16(ifd, n)) return {};
  std::uint32_t width = 0, height = 0, tile_w = 0, tile_h = 0, bps = 1, spp = 1;
  std::vector<std::uint32_t> rows_per_strip;
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::size_t e = ifd + 2 + 12 * static_cast<std::size_t>(i);
    std::uint32_t tag = 0, type = 0, count = 0;
    if (!b.u16(e, tag) || !b.u16(e + 2, type) || !b.u32(e + 4, count)) return {};
    // Every integer type libtiff converts for these tags (a TileWidth typed SSHORT is a tile width to it). The first
    // value counts; a signed one is read as its bit pattern, so a negative value only looks larger (and is refused).
    // BYTE 1, SHORT 3, LONG 4, SBYTE 6, SSHORT 8, SLONG 9, LONG8 16, SLONG8 17 (BigTIFF's, read here by libtiff too).
    const std::size_t width_bytes = type == 1 || type == 6     ? 1
                                    : type == 3 || type == 8   ? 2
                                    : type == 4 || type == 9   ? 4
                                    : type == 16 || type == 17 ? 8
                                                               : 0;
    if (width_bytes == 0) continue;
    std::size_t at = e + 8;  // inline when the values fit in the entry's 4 bytes, else at the offset stored there
    if (width_bytes * count > 4) {
      std::uint32_t offset = 0;
      if (!b.u32(e + 8, offset)) return {};
      at = offset;
    }
    std::uint32_t value = 0;
    if (width_bytes == 1) {
      if (!b.has(at, 1)) return {};
      value = b.data[at];
    } else if (width_bytes == 2) {
      if (!b.u16(at, value)) return {};
    } else if (width_bytes == 4) {
      if (!b.u32(at, value)) return {};
    } else {
      // Saturated below 2^32 - 1 (which means "one strip" for RowsPerStrip): anything that large is refused.
      std::uint32_t first = 0, second = 0;
      if (!b.u32(at, first) || !b.u32(at + 4, second)) return {};
      value = (b.big_endian ? first : second) != 0 ? 0xFFFFFFFEu : (b.big_endian ? second : first);
    }
    switch (tag) {
      case 256: width = std::max(width, value); break;
      case 257: height = std::max(height, value); break;
      case 258: bps = std::max(bps, value); break;
      case 277: spp = std::max(spp, value); break;
      case 278: rows_per_strip.push_back(value); break;
      case 322: tile_w = std::max(tile_w, value); break;
      case 323: tile_h = std::max(tile_h, value); break;
      default: break;
    }
  }
  auto h = sized(ImageFormat::Tiff, width, height);
  if (!h) return {};
  h->tiff_bits_per_sample = static_cast<int>(std::min<std::uint32_t>(bps, 1u << 20));
  h->tiff_samples_per_pixel = static_cast<int>(std::min<std::uint32_t>(spp, 1u << 20));
  // OpenCV sizes its buffer as a tile, or a strip of RowsPerStrip rows (not clamped to the height; 0 and the
  // 2^32-1 "one strip" value mean the whole image). How libtiff combines the tags is its business (a TileWidth
  // without TileLength gives tiles of RowsPerStrip rows: 1.2 GB for a 265-byte file), so the block is bounded by
  // the largest width and the largest height that any of these tags states.
  std::uint32_t block_h = std::max(height, tile_h);
  for (const std::uint32_t r : rows_per_strip) block_h = std::max(block_h, r == 0 || r == 0xFFFFFFFFu ? height : r);
  const std::uint32_t block_w = std::max(width, tile_w);
  const unsigned long long block = 1ULL * block_w * block_h;
  h->tiff_block_pixels = static_cast<long long>(std::min<unsigned long long>(block, 1ULL << 62));
  return h;
}

}  // namespace

std::optional<ImageHeader> read_image_header(const unsigned char* data, std::size_t size) {
  if (data == nullptr || size < 4) return std::nullopt;
  const Bytes b{data, size, true};
  static const unsigned char kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (size >= 8 && std::memcmp(data, kPng, 8) == 0) return png(b);
  // Each signature is the one OpenCV's decoder for the format checks, and no decoder OpenCV tries before it
  // matches these bytes: the decoder whose header was checked here is the one imdecode uses. (A "P4" not followed
  // by white space is no PNM to OpenCV, which went on to try GDCM's DICOM reader: 1.6 GB.)
  const auto space = [](unsigned char c) { return c == ' ' || (c >= '\t' && c <= '\r'); };
  if (data[0] == 'P' && data[1] >= '1' && data[1] <= '6' && space(data[2])) return pnm(b);
  if (data[0] == 0xFF && data[1] == 0xD8 && data[2] == 0xFF) return jpeg(b);
  if (data[0] == 'B' && data[1] == 'M') return bmp(Bytes{data, size, false});
  if ((std::memcmp(data, "II*\0", 4) == 0) || (std::memcmp(data, "MM\0*", 4) == 0)) return tiff(b);
  return std::nullopt;
}

std::string image_header_problem(const ImageHeader& h) {
  if (h.width > kMaxImageSide || h.height > kMaxImageSide || h.width * h.height > kMaxImagePixels) {
    return fmt::format("declares {}x{} px, more than the {} px a side and {} px in all that are accepted", h.width,
                       h.height, kMaxImageSide, kMaxImagePixels);
  }
  if (h.format == ImageFormat::Tiff) {
    if (h.tiff_bits_per_sample > 16 || h.tiff_samples_per_pixel > 4) {
      return fmt::format("is a TIFF of {} samples of {} bits per pixel (at most 4 of 16 are accepted)",
                         h.tiff_samples_per_pixel, h.tiff_bits_per_sample);
    }
    if (h.tiff_block_pixels > kMaxImagePixels) {
      return fmt::format("is a TIFF whose strips or tiles hold {} px, more than the {} accepted", h.tiff_block_pixels,
                         kMaxImagePixels);
    }
  }
  return {};
}

std::string to_string(ImageFormat format) {
  switch (format) {
    case ImageFormat::Png: return "PNG";
    case ImageFormat::Pnm: return "PNM";
    case ImageFormat::Jpeg: return "JPEG";
    case ImageFormat::Bmp: return "BMP";
    case ImageFormat::Tiff: return "TIFF";
  }
  return "unknown";
}

}  // namespace rtslam::io
