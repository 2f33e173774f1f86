#include "rtslam/io/png_grey.hpp"

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include <libdeflate.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace rtslam::io {
namespace {

std::uint32_t be32(const unsigned char* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | std::uint32_t{p[3]};
}

bool is_type(const unsigned char* p, const char* t) { return std::memcmp(p, t, 4) == 0; }

/// One decompressor per thread (allocation is ~32 KB; decoding threads reuse theirs).
libdeflate_decompressor* thread_decompressor() {
  struct Holder {
    libdeflate_decompressor* d = libdeflate_alloc_decompressor();
    ~Holder() { libdeflate_free_decompressor(d); }
  };
  thread_local Holder holder;
  return holder.d;
}

/// PNG filter types on 1 byte per pixel (PNG specification, section 9). The row above the first is zeros. Paeth in
/// libpng's form (pa = |b − c|, pb = |a − c|, pc = |a + b − 2c|), branch-free selects: each pixel depends on the one
/// before, so the loop is a chain and every cycle in it counts.
bool unfilter_rows(const unsigned char* filtered, int width, int height, cv::Mat& out) {
  const auto w = static_cast<std::size_t>(width);
  const std::vector<unsigned char> zeros(w, 0);
  const unsigned char* prev = zeros.data();
  for (int y = 0; y < height; ++y) {
    const unsigned char* src = filtered + static_cast<std::size_t>(y) * (w + 1);
    const int type = src[0];
    ++src;
    unsigned char* dst = out.ptr<unsigned char>(y);
    switch (type) {
      case 0:
        std::memcpy(dst, src, w);
        break;
      case 1: {  // Sub: the row is the running sum (mod 256) of its bytes
        std::size_t x = 0;
        unsigned left = 0;
#if defined(__SSE2__)
        // 16 bytes at a time (the rendered sequences, e.g. /work/data/v101r, filter every row with Sub, and its
        // byte-by-byte chain was ~15 % of their decoding; real EuRoC images are mostly Paeth and Average): the
        // block's own prefix sum in four shifted adds, plus the previous block's last byte in every lane. Only that
        // broadcast (3 shuffles) chains one block to the next.
        __m128i carry = _mm_setzero_si128();
        for (; x + 16 <= w; x += 16) {
          __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(src + x));
          v = _mm_add_epi8(v, _mm_slli_si128(v, 1));
          v = _mm_add_epi8(v, _mm_slli_si128(v, 2));
          v = _mm_add_epi8(v, _mm_slli_si128(v, 4));
          v = _mm_add_epi8(v, _mm_slli_si128(v, 8));
          v = _mm_add_epi8(v, carry);
          _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + x), v);
          const __m128i hi = _mm_shufflehi_epi16(_mm_unpackhi_epi8(v, v), 0xFF);  // words 4..7: byte 15 twice
          carry = _mm_shuffle_epi32(hi, 0xFF);
        }
        if (x > 0) left = dst[x - 1];
#endif
        for (; x < w; ++x) left = dst[x] = static_cast<unsigned char>(src[x] + left);
        break;
      }
      case 2:  // Up
        for (std::size_t x = 0; x < w; ++x) dst[x] = static_cast<unsigned char>(src[x] + prev[x]);
        break;
      case 3: {  // Average
        unsigned left = 0;
        for (std::size_t x = 0; x < w; ++x)
          left = dst[x] = static_cast<unsigned char>(src[x] + ((left + prev[x]) >> 1));
        break;
      }
      case 4: {  // Paeth
        int a = 0, c = 0;
        for (std::size_t x = 0; x < w; ++x) {
          const int b = prev[x];
          const int pa = std::abs(b - c), pb = std::abs(a - c), pc = std::abs(a + b - 2 * c);
          const int bc = pb <= pc ? b : c;
          const int pred = (pa <= pb && pa <= pc) ? a : bc;
          a = dst[x] = static_cast<unsigned char>(src[x] + pred);
          c = b;
        }
        break;
      }
      default:
        return false;
    }
    prev = dst;
  }
  return true;
}

}  // namespace

bool png_truncated(const unsigned char* data, std::size_t size) {
  static constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (size < 8 || std::memcmp(data, kSignature, 8) != 0) return false;
  std::size_t pos = 8;
  while (true) {
    if (size - pos < 12) return true;
    const std::uint32_t len = be32(data + pos);
    if (len > size - pos - 12) return true;
    if (is_type(data + pos + 4, "IEND")) return false;
    pos += 12 + len;
  }
}

bool decode_png_grey8(const unsigned char* data, std::size_t size, std::size_t max_pixels, cv::Mat& out) {
  static constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (size < 8 + 25 + 12 || std::memcmp(data, kSignature, 8) != 0) return false;
  std::size_t pos = 8;
  int width = 0, height = 0;
  bool ihdr = false, iend = false, idat_done = false;
  // Buffers kept per thread: a fresh 360 KB one per image costs page faults and zeroing (a tenth of the decode).
  thread_local std::vector<unsigned char> idat, raw;
  idat.clear();
  const unsigned char* single_idat = nullptr;  // one IDAT chunk (the usual case): inflated in place, no copy
  std::size_t single_size = 0;
  int idat_chunks = 0;
  while (!iend) {
    if (size - pos < 12) return false;
    const std::uint32_t len = be32(data + pos);
    if (len > size - pos - 12) return false;
    const unsigned char* type = data + pos + 4;
    const unsigned char* body = data + pos + 8;
    if (libdeflate_crc32(0, type, len + 4) != be32(body + len)) return false;
    if (!ihdr) {
      if (!is_type(type, "IHDR") || len != 13) return false;
      const std::uint32_t w = be32(body), h = be32(body + 4);
      // bit depth 8, colour type 0 (grey), compression 0, filter 0, interlace 0
      if (w == 0 || h == 0 || w > (1u << 20) || h > (1u << 20) || body[8] != 8 || body[9] != 0 || body[10] != 0 ||
          body[11] != 0 || body[12] != 0) {
        return false;
      }
      if (static_cast<std::size_t>(w) * h > max_pixels) return false;
      width = static_cast<int>(w);
      height = static_cast<int>(h);
      ihdr = true;
    } else if (is_type(type, "IDAT")) {
      if (idat_done) return false;
      if (++idat_chunks == 1) {
        single_idat = body;
        single_size = len;
      } else {
        if (idat_chunks == 2) idat.assign(single_idat, single_idat + single_size);
        idat.insert(idat.end(), body, body + len);
      }
    } else {
      if (idat_chunks > 0) idat_done = true;
      if (is_type(type, "IEND")) {
        iend = true;
      } else if ((type[0] & 0x20) == 0 || is_type(type, "tRNS") || is_type(type, "gAMA") || is_type(type, "sRGB") ||
                 is_type(type, "iCCP") || is_type(type, "cHRM") || is_type(type, "sBIT")) {
        return false;  // an unknown critical chunk, or one that could change the pixels libpng gives
      }
    }
    pos += 12 + len;
  }
  if (idat_chunks == 0) return false;
  const unsigned char* z = idat_chunks == 1 ? single_idat : idat.data();
  const std::size_t z_size = idat_chunks == 1 ? single_size : idat.size();
  const std::size_t raw_size = static_cast<std::size_t>(height) * (static_cast<std::size_t>(width) + 1);
  if (raw.size() < raw_size) raw.resize(raw_size);
  std::size_t got = 0;
  if (libdeflate_zlib_decompress(thread_decompressor(), z, z_size, raw.data(), raw_size, &got) != LIBDEFLATE_SUCCESS ||
      got != raw_size) {
    return false;
  }
  out.create(height, width, CV_8UC1);
  return unfilter_rows(raw.data(), width, height, out);
}

}  // namespace rtslam::io
