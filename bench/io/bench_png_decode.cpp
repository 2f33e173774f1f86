// PNG decoders on real dataset images: OpenCV's imdecode (what io::decode_grey_image uses), libpng's simplified API
// called directly, and libspng when the build found it (RTSLAM_BENCH_SPNG). Every decoder reads the same bytes from
// memory and must give the same pixels (checked once before timing); BM_ReadGreyImage adds reading the file.
// Images: the first 50 PNGs of $RTSLAM_BENCH_PNG_DIR (e.g. a EuRoC mav0/cam0/data folder); skipped when unset.
// Run: RTSLAM_BENCH_PNG_DIR=/path/mav0/cam0/data build/bench/io/bench_io --benchmark_repetitions=3
//        --benchmark_report_aggregates_only=true
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <png.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#ifdef RTSLAM_BENCH_SPNG
#include <spng.h>
#endif

#include "rtslam/io/png_grey.hpp"
#include "rtslam/io/source.hpp"

namespace {

using Bytes = std::vector<unsigned char>;

const std::vector<std::filesystem::path>& image_paths() {
  static const std::vector<std::filesystem::path> paths = [] {
    std::vector<std::filesystem::path> out;
    const char* dir = std::getenv("RTSLAM_BENCH_PNG_DIR");
    if (!dir) return out;
    for (const auto& e : std::filesystem::directory_iterator(dir))
      if (e.path().extension() == ".png") out.push_back(e.path());
    std::sort(out.begin(), out.end());
    out.resize(std::min<std::size_t>(out.size(), 50));
    return out;
  }();
  return paths;
}

const std::vector<Bytes>& images() {
  static const std::vector<Bytes> files = [] {
    std::vector<Bytes> out;
    for (const auto& p : image_paths()) {
      std::ifstream in(p, std::ios::binary);
      out.emplace_back((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    }
    return out;
  }();
  return files;
}

cv::Mat decode_opencv(const Bytes& b) {
  return cv::imdecode(cv::Mat(1, static_cast<int>(b.size()), CV_8UC1, const_cast<unsigned char*>(b.data())),
                      cv::IMREAD_GRAYSCALE);
}

cv::Mat decode_libpng(const Bytes& b) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_memory(&image, b.data(), b.size())) throw std::runtime_error(image.message);
  image.format = PNG_FORMAT_GRAY;
  cv::Mat out(static_cast<int>(image.height), static_cast<int>(image.width), CV_8UC1);
  if (!png_image_finish_read(&image, nullptr, out.data, static_cast<png_int_32>(out.step), nullptr)) {
    throw std::runtime_error(image.message);
  }
  return out;
}

#ifdef RTSLAM_BENCH_SPNG
cv::Mat decode_spng(const Bytes& b) {
  spng_ctx* ctx = spng_ctx_new(0);
  spng_set_png_buffer(ctx, b.data(), b.size());
  spng_ihdr ihdr{};
  if (spng_get_ihdr(ctx, &ihdr) != 0 || ihdr.color_type != SPNG_COLOR_TYPE_GRAYSCALE || ihdr.bit_depth != 8) {
    spng_ctx_free(ctx);
    throw std::runtime_error("spng: not an 8-bit grey PNG");
  }
  cv::Mat out(static_cast<int>(ihdr.height), static_cast<int>(ihdr.width), CV_8UC1);
  const int rc = spng_decode_image(ctx, out.data, out.total(), SPNG_FMT_RAW, 0);
  spng_ctx_free(ctx);
  if (rc != 0) throw std::runtime_error(spng_strerror(rc));
  return out;
}
#endif

cv::Mat decode_libdeflate(const Bytes& b) {
  cv::Mat out;
  if (!rtslam::io::decode_png_grey8(b.data(), b.size(), std::size_t{1} << 28, out)) {
    throw std::runtime_error("not an 8-bit grey PNG");
  }
  return out;
}

template <cv::Mat (*Decode)(const Bytes&)>
void BM_Decode(benchmark::State& st) {
  const auto& files = images();
  if (files.empty()) {
    st.SkipWithError("set RTSLAM_BENCH_PNG_DIR to a folder of PNGs (e.g. a EuRoC mav0/cam0/data)");
    return;
  }
  for (const auto& b : files) {  // same pixels as the library's decoder
    const cv::Mat ref = rtslam::io::decode_grey_image(b.data(), b.size());
    if (cv::norm(ref, Decode(b), cv::NORM_INF) != 0) {
      st.SkipWithError("decoders disagree");
      return;
    }
  }
  std::size_t i = 0;
  for (auto _ : st) {
    cv::Mat m = Decode(files[i++ % files.size()]);
    benchmark::DoNotOptimize(m.data);
  }
  st.SetItemsProcessed(st.iterations());
}
BENCHMARK(BM_Decode<decode_opencv>)->Name("BM_DecodeOpenCV")->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Decode<decode_libpng>)->Name("BM_DecodeLibpng")->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Decode<decode_libdeflate>)->Name("BM_DecodeLibdeflate")->Unit(benchmark::kMillisecond);
#ifdef RTSLAM_BENCH_SPNG
BENCHMARK(BM_Decode<decode_spng>)->Name("BM_DecodeSpng")->Unit(benchmark::kMillisecond);
#endif

// The library's own path from file bytes (header checks + imdecode), for reference.
void BM_DecodeGreyImage(benchmark::State& st) {
  const auto& files = images();
  if (files.empty()) {
    st.SkipWithError("set RTSLAM_BENCH_PNG_DIR");
    return;
  }
  std::size_t i = 0;
  for (auto _ : st) {
    const auto& b = files[i++ % files.size()];
    cv::Mat m = rtslam::io::decode_grey_image(b.data(), b.size());
    benchmark::DoNotOptimize(m.data);
  }
  st.SetItemsProcessed(st.iterations());
}
BENCHMARK(BM_DecodeGreyImage)->Unit(benchmark::kMillisecond);

// What a decoding thread does per image: read the file (from the page cache after the first pass) and decode it.
void BM_ReadGreyImage(benchmark::State& st) {
  const auto& paths = image_paths();
  if (paths.empty()) {
    st.SkipWithError("set RTSLAM_BENCH_PNG_DIR");
    return;
  }
  std::size_t i = 0;
  for (auto _ : st) {
    cv::Mat m = rtslam::io::read_grey_image(paths[i++ % paths.size()].string());
    if (m.empty()) {
      st.SkipWithError("an image could not be read");
      return;
    }
    benchmark::DoNotOptimize(m.data);
  }
  st.SetItemsProcessed(st.iterations());
}
BENCHMARK(BM_ReadGreyImage)->Unit(benchmark::kMillisecond);

}  // namespace
