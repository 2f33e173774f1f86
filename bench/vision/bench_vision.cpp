// Micro-benchmarks of the image-processing front end, against the targets of issue 3:
//   integral image of 752x480 <= 0.2 ms; Harris best corner in a 64x64 ROI <= 20 us;
//   two-level ZNCC of a 15x15 patch over a 41x41 region <= 20 us; one 31x31 -> 15x15 warp <= 5 us.
// Run: build/bench/vision/bench_vision --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
// Real frames come from ../shared/datasets (EuRoC cam0, MonoSLAM); a benchmark reports an error if they are absent.
// The simd argument selects the kernels (0 scalar, 1 SSE2, 2 AVX2; see rtslam/vision/simd.hpp); a level the CPU
// does not run is reported as an error.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/imgcodecs.hpp>

#include "rtslam/vision/harris.hpp"
#include "rtslam/vision/integral.hpp"
#include "rtslam/vision/simd.hpp"
#include "rtslam/vision/warp.hpp"
#include "rtslam/vision/zncc.hpp"

using namespace rtslam::vision;

namespace {

const std::string kData = std::string(RTSLAM_SOURCE_DIR) + "/../shared/datasets";

Image load(const std::string& path) {
  if (!std::filesystem::exists(path)) return {};
  const cv::Mat m = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (m.empty()) return {};
  Image img(m.cols, m.rows);
  for (int v = 0; v < m.rows; ++v)
    for (int u = 0; u < m.cols; ++u) img.at(u, v) = m.at<std::uint8_t>(v, u);
  return img;
}

const Image& euroc_frame() {
  static const Image img = [] {
    const std::string dir = kData + "/euroc-v101-static/mav0/cam0/data";
    if (!std::filesystem::is_directory(dir)) return Image{};
    std::vector<std::string> files;
    for (const auto& e : std::filesystem::directory_iterator(dir)) files.push_back(e.path().string());
    std::sort(files.begin(), files.end());
    return files.empty() ? Image{} : load(files.front());
  }();
  return img;
}

std::string mono_path(int k) {
  char name[64];
  std::snprintf(name, sizeof(name), "/monoslam-davison/frames/rawoutput%04d.pgm", k);
  return kData + name;
}

// Selects the SIMD level of state.range(arg) for one benchmark; false (and an error) if the CPU does not run it.
class SimdScope {
 public:
  SimdScope(benchmark::State& state, int arg) : previous_(simd_level()) {
    const auto level = static_cast<SimdLevel>(state.range(arg));
    ok_ = set_simd_level(level) == level;
    if (!ok_) state.SkipWithError("SIMD level not supported by this CPU");
  }
  ~SimdScope() { set_simd_level(previous_); }
  bool ok() const { return ok_; }
  const char* name() const { return to_string(simd_level()); }

 private:
  SimdLevel previous_;
  bool ok_ = false;
};

void BM_IntegralImage752x480(benchmark::State& state) {
  const Image& img = euroc_frame();
  if (img.empty()) return state.SkipWithError("dataset euroc-v101-static not found");
  const SimdScope simd(state, 1);
  if (!simd.ok()) return;
  const bool squares = state.range(0) != 0;
  IntegralImages ii;
  for (auto _ : state) {
    ii.compute(img, squares);
    benchmark::DoNotOptimize(ii.sum_table());
    benchmark::ClobberMemory();
  }
  state.SetLabel(std::string(squares ? "sum + squared sum, " : "sum only, ") + simd.name());
}
BENCHMARK(BM_IntegralImage752x480)
    ->ArgNames({"squares", "simd"})
    ->Args({1, 2})
    ->Args({0, 2})
    ->Args({1, 1})
    ->Args({1, 0})
    ->Unit(benchmark::kMicrosecond);

// What bounds the integral image: the memory traffic of its two uint32 tables alone, same buffers and layout.
// Arg 0: each table row is the row above plus a constant (the loads and stores of the integral image without its
// prefix sums); arg 1: the tables are filled (stores only).
void BM_IntegralTableTraffic752x480(benchmark::State& state) {
  const int w = 752, h = 480, stride = w + 1;
  std::vector<std::uint32_t> sum(static_cast<std::size_t>(stride) * (h + 1), 0);
  std::vector<std::uint32_t> sq(sum.size(), 0);
  const bool fill_only = state.range(0) != 0;
  for (auto _ : state) {
    if (fill_only) {
      std::fill(sum.begin(), sum.end(), 1u);
      std::fill(sq.begin(), sq.end(), 2u);
    } else {
      for (int y = 1; y <= h; ++y) {
        std::uint32_t* s = sum.data() + static_cast<std::size_t>(y) * stride;
        std::uint32_t* q = sq.data() + static_cast<std::size_t>(y) * stride;
        for (int x = 1; x <= w; ++x) {
          s[x] = s[x - stride] + 1;
          q[x] = q[x - stride] + 2;
        }
      }
    }
    benchmark::DoNotOptimize(sum.data());
    benchmark::DoNotOptimize(sq.data());
    benchmark::ClobberMemory();
  }
  state.SetLabel(fill_only ? "fill of both tables" : "row above + constant, both tables");
}
BENCHMARK(BM_IntegralTableTraffic752x480)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// Harris best corner in 64x64 cells of a real frame (cycling over the cells of the frame).
void BM_HarrisBestCorner64x64(benchmark::State& state) {
  const Image& img = euroc_frame();
  if (img.empty()) return state.SkipWithError("dataset euroc-v101-static not found");
  const SimdScope simd(state, 1);
  if (!simd.ok()) return;
  HarrisOptions o;
  o.response = state.range(0) == 0 ? HarrisResponse::harris : HarrisResponse::min_eigen;
  HarrisDetector det(o);
  std::vector<Roi> cells;
  for (int y = 16; y + 64 <= img.height() - 16; y += 64)
    for (int x = 16; x + 64 <= img.width() - 16; x += 64) cells.push_back(Roi{x, y, 64, 64});
  std::size_t i = 0, found = 0;
  for (auto _ : state) {
    const auto c = det.best_corner(img, cells[i]);
    found += c.has_value();
    benchmark::DoNotOptimize(c);
    i = (i + 1) % cells.size();
  }
  state.SetLabel(std::string(o.response == HarrisResponse::harris ? "harris, " : "min_eigen, ") + simd.name());
  state.counters["found_rate"] = static_cast<double>(found) / static_cast<double>(state.iterations());
}
BENCHMARK(BM_HarrisBestCorner64x64)
    ->ArgNames({"min_eigen", "simd"})
    ->Args({0, 2})
    ->Args({1, 2})
    ->Args({0, 1})
    ->Args({0, 0})
    ->Unit(benchmark::kMicrosecond);

// ZNCC of Harris-selected 15x15 patches of MonoSLAM frame k searched over 41x41 positions in frame k + 1.
struct TrackingSet {
  Image f1;
  std::vector<Patch> patches;
  std::vector<Eigen::Vector2d> centres;
};

const TrackingSet& tracking_set() {
  static const TrackingSet set = [] {
    TrackingSet s;
    const Image f0 = load(mono_path(300));
    s.f1 = load(mono_path(301));
    if (f0.empty() || s.f1.empty()) return TrackingSet{};
    HarrisOptions o;
    o.border_px = 7 + 20;
    HarrisDetector det(o);
    for (int y = 0; y < f0.height(); y += 32)
      for (int x = 0; x < f0.width(); x += 32)
        if (auto c = det.best_corner(f0, Roi{x, y, 32, 32})) {
          Patch p;
          p.extract(f0, c->u_px, c->v_px, 15);
          s.patches.push_back(p);
          s.centres.emplace_back(c->u_px, c->v_px);
        }
    return s;
  }();
  return set;
}

void BM_Zncc15x15Over41x41(benchmark::State& state) {
  const TrackingSet& set = tracking_set();
  if (set.patches.empty()) return state.SkipWithError("dataset monoslam-davison not found");
  const SimdScope simd(state, 2);
  if (!simd.ok()) return;
  ZnccOptions o;
  o.two_level = state.range(0) != 0;
  o.partial_correlation = state.range(1) != 0;
  ZnccMatcher m(o);
  std::size_t i = 0, found = 0;
  double evaluated = 0;
  for (auto _ : state) {
    const MatchResult r = m.match(set.patches[i], set.f1, SearchEllipse::box(set.centres[i], 20.0, 20.0));
    found += r.found;
    evaluated += r.n_evaluated;
    benchmark::DoNotOptimize(r);
    i = (i + 1) % set.patches.size();
  }
  state.SetLabel(std::string(o.two_level ? "two-level" : "exhaustive") +
                 (o.partial_correlation ? " + bounded partial correlation, " : ", ") + simd.name());
  state.counters["found_rate"] = static_cast<double>(found) / static_cast<double>(state.iterations());
  state.counters["positions"] = evaluated / static_cast<double>(state.iterations());
}
BENCHMARK(BM_Zncc15x15Over41x41)
    ->ArgNames({"two_level", "partial", "simd"})
    ->Args({1, 1, 1})
    ->Args({1, 0, 1})
    ->Args({0, 1, 1})
    ->Args({0, 0, 1})
    ->Args({1, 1, 0})
    ->Unit(benchmark::kMicrosecond);

void BM_PredictAppearance31To15(benchmark::State& state) {
  std::vector<std::uint8_t> init_pixels(31 * 31);
  for (std::size_t i = 0; i < init_pixels.size(); ++i) init_pixels[i] = static_cast<std::uint8_t>((i * 37) % 251);
  const ImageView init{init_pixels.data(), 31, 31, 31};
  const PinholeIntrinsics K{300.0, 300.0, 160.0, 120.0};
  RigidPose T0, T1;
  T1.R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.1, 0.2, 1.0).normalized()).toRotationMatrix();
  T1.t = Eigen::Vector3d(0.1, -0.05, 0.4);
  const Eigen::Vector3d p_W(0.1, 0.05, 2.0);
  const Eigen::Vector2d c0(175.0, 127.5);
  Image out(15, 15);
  int outside = 0;
  for (auto _ : state) {
    const WarpResult r = predict_appearance(init, c0, K, T0, T1, p_W, out.mutable_view());
    outside = r.n_outside;
    benchmark::DoNotOptimize(r);
    benchmark::ClobberMemory();
  }
  state.counters["outside_px"] = outside;
}
BENCHMARK(BM_PredictAppearance31To15)->Unit(benchmark::kMicrosecond);

}  // namespace
