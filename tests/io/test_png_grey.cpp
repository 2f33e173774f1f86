// The 8-bit grey PNG fast path (png_grey.hpp) gives exactly libpng's pixels (through OpenCV) for every PNG filter
// type, split image data and extra chunks, and declines (returns false) everything it does not handle, so that
// OpenCV decides. PNGs are written here chunk by chunk with the filter of each row chosen.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <libdeflate.h>
#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*, cv::IMWRITE_*

#include "io_test_util.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/io/image_header.hpp"
#include "rtslam/io/png_grey.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::io {
namespace {

using Bytes = std::vector<unsigned char>;
constexpr std::size_t kMaxPixels = 1 << 24;

void put32(Bytes& b, std::uint32_t v) {
  for (int s = 24; s >= 0; s -= 8) b.push_back(static_cast<unsigned char>(v >> s));
}

void chunk(Bytes& png, const char* type, const Bytes& body) {
  put32(png, static_cast<std::uint32_t>(body.size()));
  const std::size_t start = png.size();
  png.insert(png.end(), type, type + 4);
  png.insert(png.end(), body.begin(), body.end());
  put32(png, static_cast<std::uint32_t>(libdeflate_crc32(0, png.data() + start, body.size() + 4)));
}

/// Filters row y of `img` with PNG filter `type` (1 byte per pixel).
Bytes filter_row(const cv::Mat& img, int y, int type) {
  Bytes out = {static_cast<unsigned char>(type)};
  for (int x = 0; x < img.cols; ++x) {
    const int a = x > 0 ? img.at<unsigned char>(y, x - 1) : 0;
    const int b = y > 0 ? img.at<unsigned char>(y - 1, x) : 0;
    const int c = x > 0 && y > 0 ? img.at<unsigned char>(y - 1, x - 1) : 0;
    int pred = 0;
    if (type == 1) pred = a;
    if (type == 2) pred = b;
    if (type == 3) pred = (a + b) / 2;
    if (type == 4) {
      const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
      pred = (pa <= pb && pa <= pc) ? a : (pb <= pc ? b : c);
    }
    out.push_back(static_cast<unsigned char>(img.at<unsigned char>(y, x) - pred));
  }
  return out;
}

struct PngSpec {
  int bit_depth = 8, colour_type = 0, interlace = 0;
  int idat_parts = 1;
  std::vector<std::pair<std::string, Bytes>> extra;  // chunks between IHDR and IDAT
};

Bytes make_png(const cv::Mat& img, const PngSpec& spec = {}) {
  Bytes png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  Bytes ihdr;
  put32(ihdr, static_cast<std::uint32_t>(img.cols));
  put32(ihdr, static_cast<std::uint32_t>(img.rows));
  ihdr.insert(ihdr.end(), {static_cast<unsigned char>(spec.bit_depth), static_cast<unsigned char>(spec.colour_type), 0,
                           0, static_cast<unsigned char>(spec.interlace)});
  chunk(png, "IHDR", ihdr);
  for (const auto& [type, body] : spec.extra) chunk(png, type.c_str(), body);
  Bytes raw;
  for (int y = 0; y < img.rows; ++y) {
    const Bytes row = filter_row(img, y, y % 5);  // every filter type, in turn
    raw.insert(raw.end(), row.begin(), row.end());
  }
  libdeflate_compressor* c = libdeflate_alloc_compressor(6);
  Bytes z(libdeflate_zlib_compress_bound(c, raw.size()));
  z.resize(libdeflate_zlib_compress(c, raw.data(), raw.size(), z.data(), z.size()));
  libdeflate_free_compressor(c);
  const std::size_t part = z.size() / static_cast<std::size_t>(spec.idat_parts) + 1;
  for (std::size_t i = 0; i < z.size(); i += part) {
    chunk(png, "IDAT",
          Bytes(z.begin() + static_cast<std::ptrdiff_t>(i),
                z.begin() + static_cast<std::ptrdiff_t>(std::min(z.size(), i + part))));
  }
  chunk(png, "IEND", {});
  return png;
}

cv::Mat textured(int w, int h) {
  cv::Mat img(h, w, CV_8UC1);
  cv::RNG rng(3);
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  img.row(0).setTo(255);  // saturated values and wrap-around in the filters
  img.col(0).setTo(0);
  return img;
}

cv::Mat opencv_decode(const Bytes& png) {
  return io::codecs::imdecode(cv::Mat(1, static_cast<int>(png.size()), CV_8UC1, const_cast<unsigned char*>(png.data())),
                      cv::IMREAD_GRAYSCALE);
}

TEST(PngGrey, EveryFilterTypeGivesLibpngsPixels) {
  // Widths below, at and between multiples of 16 (the Sub filter's vector blocks and their scalar tail).
  for (const auto& [w, h] : {std::pair{1, 1}, {7, 5}, {16, 6}, {33, 7}, {47, 6}, {64, 48}, {752, 31}}) {
    const cv::Mat img = textured(w, h);
    for (int parts : {1, 3}) {
      PngSpec spec;
      spec.idat_parts = parts;
      spec.extra = {{"tEXt", Bytes{'k', 0, 'v'}}};  // ancillary chunks without effect on pixels are skipped
      const Bytes png = make_png(img, spec);
      cv::Mat fast;
      ASSERT_TRUE(decode_png_grey8(png.data(), png.size(), kMaxPixels, fast)) << w << "x" << h;
      const cv::Mat ref = opencv_decode(png);
      ASSERT_EQ(ref.size(), img.size());
      EXPECT_EQ(cv::norm(fast, img, cv::NORM_INF), 0.0) << w << "x" << h << ", " << parts << " IDAT chunks";
      EXPECT_EQ(cv::norm(fast, ref, cv::NORM_INF), 0.0);
      EXPECT_EQ(cv::norm(decode_grey_image(png.data(), png.size()), img, cv::NORM_INF), 0.0);
    }
  }
}

TEST(PngGrey, DeclinesWhatItDoesNotHandleAndDamage) {
  const cv::Mat img = textured(16, 8);
  cv::Mat out;
  const auto declines = [&](const Bytes& png) { return !decode_png_grey8(png.data(), png.size(), kMaxPixels, out); };
  const auto spec = [](auto change) {
    PngSpec s;
    change(s);
    return s;
  };
  EXPECT_TRUE(declines(make_png(img, spec([](PngSpec& s) { s.bit_depth = 16; }))));
  EXPECT_TRUE(declines(make_png(img, spec([](PngSpec& s) { s.colour_type = 2; }))));
  EXPECT_TRUE(declines(make_png(img, spec([](PngSpec& s) { s.interlace = 1; }))));
  EXPECT_TRUE(declines(make_png(img, spec([](PngSpec& s) { s.extra = {{"tRNS", Bytes{0, 0}}}; }))));
  EXPECT_TRUE(declines(make_png(img, spec([](PngSpec& s) { s.extra = {{"gAMA", Bytes{0, 0, 0xb1, 0x8f}}}; }))));
  const Bytes good = make_png(img);
  EXPECT_FALSE(declines(good));
  EXPECT_FALSE(decode_png_grey8(good.data(), good.size(), 16 * 8 - 1, out)) << "over the pixel limit";
  for (std::size_t cut : {good.size() - 1, good.size() - 12, good.size() / 2, std::size_t{20}}) {
    EXPECT_TRUE(declines(Bytes(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(cut)))) << cut;
  }
  Bytes flipped = good;
  flipped[flipped.size() / 2] ^= 0x10;  // inside IDAT: its CRC fails
  EXPECT_TRUE(declines(flipped));
  // The library path still reports the damaged file as undecodable (OpenCV's verdict).
  std::string why;
  EXPECT_TRUE(decode_grey_image(flipped.data(), flipped.size(), &why).empty());
  EXPECT_NE(why.find("cannot be decoded"), std::string::npos) << why;
}

TEST(PngGrey, TruncationIsToldFromTheChunkHeaders) {
  PngSpec parts;
  parts.idat_parts = 3;
  const Bytes whole = make_png(textured(40, 30), parts);
  EXPECT_FALSE(png_truncated(whole.data(), whole.size()));
  Bytes tail = whole;  // bytes after IEND do not matter
  tail.insert(tail.end(), {1, 2, 3});
  EXPECT_FALSE(png_truncated(tail.data(), tail.size()));
  for (const std::size_t cut : {whole.size() - 1, whole.size() - 12, whole.size() / 2, std::size_t{40},
                                std::size_t{9}}) {
    EXPECT_TRUE(png_truncated(whole.data(), cut)) << cut;
  }
  PngSpec rgb;
  rgb.colour_type = 2;
  const Bytes colour = make_png(cv::Mat(4, 4, CV_8UC3, cv::Scalar(1, 2, 3)), rgb);
  EXPECT_TRUE(png_truncated(colour.data(), colour.size() - 5));  // any colour type: headers only
  const unsigned char not_png[] = {'n', 'o', 't', ' ', 'a', ' ', 'p', 'n', 'g'};
  EXPECT_FALSE(png_truncated(not_png, sizeof not_png));
}

TEST(PngGrey, OpenCvWrittenPngsDecodeTheSame) {
  const cv::Mat img = textured(97, 33);
  for (int level : {0, 1, 9}) {
    std::vector<unsigned char> png;
    ASSERT_TRUE(io::codecs::imencode(".png", img, png, {cv::IMWRITE_PNG_COMPRESSION, level}));
    cv::Mat fast;
    ASSERT_TRUE(decode_png_grey8(png.data(), png.size(), kMaxPixels, fast)) << "level " << level;
    EXPECT_EQ(cv::norm(fast, img, cv::NORM_INF), 0.0) << "level " << level;
  }
}

void write_bytes(const std::string& path, const Bytes& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

// read_grey_image reads into a buffer its thread keeps: a file read after a larger one must give only its own bytes,
// a file of unknown size (a pipe) is read in blocks, and a file larger than any image is refused unread.
TEST(ReadGreyImage, ReadsEachFileWholeWhateverCameBefore) {
  test::TempDir dir;
  const cv::Mat big = textured(512, 400), small = textured(17, 9);
  Bytes big_png, small_png;
  ASSERT_TRUE(io::codecs::imencode(".png", big, big_png, {cv::IMWRITE_PNG_COMPRESSION, 0}));
  ASSERT_TRUE(io::codecs::imencode(".png", small, small_png));
  ASSERT_GT(big_png.size(), std::size_t{3} << 16);  // several of the blocks a file of unknown size is read in
  write_bytes(dir / "big.png", big_png);
  write_bytes(dir / "small.png", small_png);
  for (const char* name : {"big.png", "small.png", "big.png", "small.png"}) {
    std::string why;
    const cv::Mat img = read_grey_image(dir / name, &why);
    ASSERT_FALSE(img.empty()) << name << ": " << why;
    EXPECT_EQ(cv::norm(img, std::string(name) == "big.png" ? big : small, cv::NORM_INF), 0.0) << name;
  }
  // The big file cut short, read after the whole one: the buffer still holds the missing tail, which must not
  // complete it.
  write_bytes(dir / "cut.png", Bytes(big_png.begin(), big_png.end() - 30));
  ASSERT_FALSE(read_grey_image(dir / "big.png").empty());
  std::string why;
  EXPECT_TRUE(read_grey_image(dir / "cut.png", &why).empty());
  EXPECT_NE(why.find("cannot be decoded"), std::string::npos) << why;

  // A named pipe has no size: read in blocks until its writer closes it (the PNG spans several blocks).
  const std::string fifo = dir / "pipe.png";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::thread writer([&] { write_bytes(fifo, big_png); });
  why.clear();
  const cv::Mat piped = read_grey_image(fifo, &why);
  writer.join();
  ASSERT_FALSE(piped.empty()) << why;
  EXPECT_EQ(cv::norm(piped, big, cv::NORM_INF), 0.0);

  // Larger than any image accepted (a sparse file: nothing is written or read).
  const std::string huge = dir / "huge.png";
  write_bytes(huge, small_png);
  std::filesystem::resize_file(huge, 8 * static_cast<std::uintmax_t>(kMaxImagePixels) + (2u << 20));
  why.clear();
  EXPECT_TRUE(read_grey_image(huge, &why).empty());
  EXPECT_NE(why.find("larger than any image accepted"), std::string::npos) << why;
  EXPECT_TRUE(read_grey_image(dir / "missing.png", &why).empty());
  EXPECT_EQ(why, "cannot be opened");
  // A folder opens but cannot be read: an error naming the problem, not an exception.
  why.clear();
  EXPECT_TRUE(read_grey_image(dir.str(), &why).empty());
  EXPECT_EQ(why.rfind("cannot be read", 0), 0u) << why;
}

}  // namespace
}  // namespace rtslam::io
