#include "rtslam/sim/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"

namespace rtslam::sim {

using Eigen::Vector3f;

namespace {

// splitmix64's output function: a bijection of 64-bit words that scatters nearby inputs.
std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

// Gaussian pixel noise of one image row: a splitmix64 stream and the Marsaglia polar method in float (both
// values of each accepted pair are used). ~5x cheaper per pixel than std::normal_distribution on mt19937_64,
// whose seeding and per-draw cost dominated the noise.
class RowNoise {
 public:
  RowNoise(std::uint64_t seed, float sigma) : state_(mix64(seed)), sigma_(sigma) {}
  float operator()() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    float x = 0.0f, y = 0.0f, r2 = 0.0f;
    do {
      const std::uint64_t bits = next();  // two 24-bit uniforms on [-1, 1)
      x = static_cast<float>(bits >> 40) * 0x1p-23f - 1.0f;
      y = static_cast<float>((bits >> 16) & 0xFFFFFFULL) * 0x1p-23f - 1.0f;
      r2 = x * x + y * y;
    } while (r2 >= 1.0f || r2 == 0.0f);
    const float f = sigma_ * std::sqrt(-2.0f * std::log(r2) / r2);
    spare_ = y * f;
    has_spare_ = true;
    return x * f;
  }

 private:
  std::uint64_t next() { return mix64(state_ += 0x9E3779B97F4A7C15ULL); }
  std::uint64_t state_;
  float sigma_;
  float spare_ = 0.0f;
  bool has_spare_ = false;
};

}  // namespace

Renderer::Renderer(const World& world, const models::PinholeCamera& camera, const RenderOptions& options)
    : world_(world), options_(options) {
  require_bound(options_.supersampling >= 1 && options_.supersampling <= 8, "render", "supersampling",
                options_.supersampling, "in [1, 8]");
  require_bound(options_.noise_std >= 0.0, "render", "noise_std", options_.noise_std, ">= 0 grey levels");
  require_bound(options_.exposure_s >= 0.0, "render", "exposure_s", options_.exposure_s, ">= 0 s");
  require_bound(options_.threads >= 1 && options_.threads <= 64, "render", "threads", options_.threads, "in [1, 64]");
  const auto& intr = camera.intrinsics();
  width_ = intr.width;
  height_ = intr.height;
  const int n = options_.supersampling;
  n2_ = n * n;
  rays_.assign(static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_) * static_cast<std::size_t>(n2_),
               Eigen::Vector2f::Constant(std::numeric_limits<float>::quiet_NaN()));
  auto fill = [&](int row_begin, int row_step) {
    Eigen::Vector3d ray;
    for (int v = row_begin; v < height_; v += row_step)
      for (int u = 0; u < width_; ++u)
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) {
            const Eigen::Vector2d px(u + (i + 0.5) / n - 0.5, v + (j + 0.5) / n - 0.5);
            const std::size_t idx =
                (static_cast<std::size_t>(v) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(u)) *
                    static_cast<std::size_t>(n2_) +
                static_cast<std::size_t>(j * n + i);
            if (camera.unproject(px, ray)) rays_[idx] = ray.head<2>().cast<float>();  // ray.z() = 1
          }
  };
  std::vector<std::thread> pool;
  for (int k = 1; k < options_.threads; ++k) pool.emplace_back(fill, k, options_.threads);
  fill(0, options_.threads);
  for (auto& t : pool) t.join();
  for (const Eigen::Vector2f& r : rays_) valid_rays_ += std::isnan(r.x()) ? 0 : 1;

  tiles_x_ = (width_ + kTile - 1) / kTile;
  tiles_y_ = (height_ + kTile - 1) / kTile;
  constexpr float kInf = std::numeric_limits<float>::infinity();
  tile_rays_.assign(static_cast<std::size_t>(tiles_x_) * static_cast<std::size_t>(tiles_y_),
                    Rect{kInf, -kInf, kInf, -kInf});
  tile_full_.assign(tile_rays_.size(), 1);
  for (int v = 0; v < height_; ++v)
    for (int u = 0; u < width_; ++u) {
      Rect& r = tile_rays_[static_cast<std::size_t>((v / kTile) * tiles_x_ + u / kTile)];
      const Eigen::Vector2f* ray = rays_.data() + (static_cast<std::size_t>(v) * static_cast<std::size_t>(width_) +
                                                   static_cast<std::size_t>(u)) * static_cast<std::size_t>(n2_);
      for (int k = 0; k < n2_; ++k, ++ray) {
        if (std::isnan(ray->x())) {
          tile_full_[static_cast<std::size_t>((v / kTile) * tiles_x_ + u / kTile)] = 0;
          continue;
        }
        r.x_min = std::min(r.x_min, ray->x());
        r.x_max = std::max(r.x_max, ray->x());
        r.y_min = std::min(r.y_min, ray->y());
        r.y_max = std::max(r.y_max, ray->y());
      }
    }
}

int Renderer::pose_count() const { return options_.motion_blur ? n2_ : 1; }

std::vector<double> Renderer::pose_time_offsets() const {
  const int m = pose_count();
  std::vector<double> out(static_cast<std::size_t>(m), 0.0);
  if (m > 1)
    for (int k = 0; k < m; ++k) out[static_cast<std::size_t>(k)] = options_.exposure_s * ((k + 0.5) / m - 0.5);
  return out;
}

struct Renderer::Frame {
  std::vector<Eigen::Matrix3f> R_WC;
  std::vector<Vector3f> p_WC;
  std::vector<Rect> boxes;  // per obstacle: union over the poses of its projection's bounds (empty: never seen)
};

struct Renderer::Scratch {
  std::vector<float> sums;       // [(v - v_begin) * width + u]: a block's pixel values before noise
  std::vector<int> boxes;        // the obstacles in view of a tile
  std::vector<float> o[3], d[3];  // a tile's valid sub-sample rays in W, by coordinate
  std::vector<float> grey;       // and what they see
};

#if defined(__x86_64__)
// d = R (x, y, 1) for rays k < count (count rounded down to a multiple of 8) of the interleaved table xy, written
// to the scratch columns from row n; returns how many. The same float operations as Eigen's 3x3 product: per
// coordinate R(i, 0) x + (R(i, 1) y + R(i, 2) · 1) (its unrolled sum of three terms splits as 1 + 2).
__attribute__((target("avx2"))) int Renderer::rotate_rays_avx2(const float* xy, int count, const Eigen::Matrix3f& R,
                                                               Scratch& scratch, std::size_t n) {
  const int done = count / 8 * 8;
  const __m256 one = _mm256_set1_ps(1.0f);
  for (int k = 0; k < done; k += 8) {
    const __m256 a = _mm256_loadu_ps(xy + 2 * k), b = _mm256_loadu_ps(xy + 2 * k + 8);
    // [x0 y0 x1 y1 | x2 y2 x3 y3], [x4 y4 x5 y5 | x6 y6 x7 y7] -> x0..x7 and y0..y7
    const __m256 xs = _mm256_castpd_ps(_mm256_permute4x64_pd(
        _mm256_castps_pd(_mm256_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0))), _MM_SHUFFLE(3, 1, 2, 0)));
    const __m256 ys = _mm256_castpd_ps(_mm256_permute4x64_pd(
        _mm256_castps_pd(_mm256_shuffle_ps(a, b, _MM_SHUFFLE(3, 1, 3, 1))), _MM_SHUFFLE(3, 1, 2, 0)));
    for (int i = 0; i < 3; ++i) {
      const __m256 d = _mm256_add_ps(
          _mm256_mul_ps(_mm256_set1_ps(R(i, 0)), xs),
          _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(R(i, 1)), ys), _mm256_mul_ps(_mm256_set1_ps(R(i, 2)), one)));
      _mm256_storeu_ps(scratch.d[i].data() + n + static_cast<std::size_t>(k), d);
    }
  }
  return done;
}

// out[u] = the mean of pixel u's n2 (1 or 4) consecutive grey levels, for u < pixels: the plain path's sum
// 0 + g0 + g1 + ... in the same order, then times inv_n2.
__attribute__((target("avx2"))) void Renderer::average_subsamples_avx2(const float* grey, int pixels, int n2,
                                                                        float inv_n2, float* out) {
  const __m256 zero = _mm256_setzero_ps(), scale = _mm256_set1_ps(inv_n2);
  int u = 0;
  if (n2 == 4) {
    // Eight pixels' 32 sub-samples, transposed within the 128-bit lanes: g[i] holds sub-sample i of pixels
    // 0 2 4 6 | 1 3 5 7, put back in order by the final permutation.
    const __m256i order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
    for (; u + 8 <= pixels; u += 8, grey += 32) {
      const __m256 a = _mm256_loadu_ps(grey), b = _mm256_loadu_ps(grey + 8);
      const __m256 c = _mm256_loadu_ps(grey + 16), d = _mm256_loadu_ps(grey + 24);
      const __m256 t0 = _mm256_unpacklo_ps(a, b), t1 = _mm256_unpackhi_ps(a, b);
      const __m256 t2 = _mm256_unpacklo_ps(c, d), t3 = _mm256_unpackhi_ps(c, d);
      const __m256 g0 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));
      const __m256 g1 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
      const __m256 g2 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));
      const __m256 g3 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));
      const __m256 sum = _mm256_add_ps(_mm256_add_ps(_mm256_add_ps(_mm256_add_ps(zero, g0), g1), g2), g3);
      _mm256_storeu_ps(out + u, _mm256_permutevar8x32_ps(_mm256_mul_ps(sum, scale), order));
    }
  } else {
    for (; u + 8 <= pixels; u += 8, grey += 8)
      _mm256_storeu_ps(out + u, _mm256_mul_ps(_mm256_add_ps(zero, _mm256_loadu_ps(grey)), scale));
  }
  for (; u < pixels; ++u) {
    float sum = 0.0f;
    for (int k = 0; k < n2; ++k) sum += *grey++;
    out[u] = sum * inv_n2;
  }
}

// row[u] = value[u] clamped to [0, 255] and rounded half away from zero, as the plain path: std::clamp's
// comparisons (v < 0, 255 < v) as blends, the truncation and the fraction test in vector.
__attribute__((target("avx2"))) void Renderer::quantize_row_avx2(const float* value, int width, std::uint8_t* row) {
  const __m256 lo = _mm256_setzero_ps(), hi = _mm256_set1_ps(255.0f), half = _mm256_set1_ps(0.5f);
  const __m256i one = _mm256_set1_epi32(1);
  int u = 0;
  for (; u + 8 <= width; u += 8) {
    __m256 v = _mm256_loadu_ps(value + u);
    v = _mm256_blendv_ps(v, lo, _mm256_cmp_ps(v, lo, _CMP_LT_OQ));
    v = _mm256_blendv_ps(v, hi, _mm256_cmp_ps(hi, v, _CMP_LT_OQ));
    const __m256i whole = _mm256_cvttps_epi32(v);
    const __m256 up = _mm256_cmp_ps(_mm256_sub_ps(v, _mm256_cvtepi32_ps(whole)), half, _CMP_GE_OQ);
    const __m256i q = _mm256_add_epi32(whole, _mm256_and_si256(_mm256_castps_si256(up), one));
    const __m128i q16 = _mm_packus_epi32(_mm256_castsi256_si128(q), _mm256_extracti128_si256(q, 1));
    _mm_storel_epi64(reinterpret_cast<__m128i*>(row + u), _mm_packus_epi16(q16, q16));
  }
  for (; u < width; ++u) {
    const float v = std::clamp(value[u], 0.0f, 255.0f);
    const int whole = static_cast<int>(v);
    row[u] = static_cast<std::uint8_t>(whole + (v - static_cast<float>(whole) >= 0.5f ? 1 : 0));
  }
}
#else
int Renderer::rotate_rays_avx2(const float*, int, const Eigen::Matrix3f&, Scratch&, std::size_t) { return 0; }
void Renderer::average_subsamples_avx2(const float*, int, int, float, float*) {}
void Renderer::quantize_row_avx2(const float*, int, std::uint8_t*) {}
#endif

void Renderer::render_block(const Frame& frame, std::uint64_t noise_seed, int tile_row, Scratch& scratch,
                            cv::Mat& out) const {
  std::vector<float>& sums = scratch.sums;
  std::vector<int>& boxes = scratch.boxes;
  const int m = static_cast<int>(frame.R_WC.size());
  const int v_begin = tile_row * kTile, v_end = std::min(height_, v_begin + kTile);
  const float inv_n2 = 1.0f / static_cast<float>(n2_);
  const bool vectorized = world_.vectorized();
  for (int tx = 0; tx < tiles_x_; ++tx) {
    const int u_begin = tx * kTile, u_end = std::min(width_, u_begin + kTile);
    const Rect& tile = tile_rays_[static_cast<std::size_t>(tile_row * tiles_x_ + tx)];
    boxes.clear();
    for (std::size_t k = 0; k < frame.boxes.size(); ++k) {
      const Rect& b = frame.boxes[k];
      if (b.x_min <= tile.x_max && b.x_max >= tile.x_min && b.y_min <= tile.y_max && b.y_max >= tile.y_min)
        boxes.push_back(static_cast<int>(k));
    }
    // The tile's rays are traced in one call (the per-ray work inlined in world.cpp), then summed per pixel.
    std::size_t n = 0;
    const bool whole = m == 1 && tile_full_[static_cast<std::size_t>(tile_row * tiles_x_ + tx)] != 0;
    for (int v = v_begin; v < v_end; ++v) {
      const Eigen::Vector2f* ray = rays_.data() + (static_cast<std::size_t>(v) * static_cast<std::size_t>(width_) +
                                                   static_cast<std::size_t>(u_begin)) * static_cast<std::size_t>(n2_);
      if (whole && vectorized) {  // one pose, every ray valid: the row's rays rotated eight at a time
        const int count = (u_end - u_begin) * n2_;
        // The table's Vector2f are packed pairs of floats: the row's rays are 2 count consecutive floats.
        static_assert(sizeof(Eigen::Vector2f) == 2 * sizeof(float));
        const int done = rotate_rays_avx2(reinterpret_cast<const float*>(ray), count, frame.R_WC[0], scratch, n);
        for (int k = done; k < count; ++k) {
          const Vector3f d = frame.R_WC[0] * Vector3f(ray[k].x(), ray[k].y(), 1.0f);
          for (int i = 0; i < 3; ++i) scratch.d[i][n + static_cast<std::size_t>(k)] = d[i];
        }
        for (int i = 0; i < 3; ++i)
          std::fill_n(scratch.o[i].begin() + static_cast<std::ptrdiff_t>(n), count, frame.p_WC[0][i]);
        n += static_cast<std::size_t>(count);
        continue;
      }
      for (int u = u_begin; u < u_end; ++u)
        for (int k = 0; k < n2_; ++k, ++ray) {
          if (std::isnan(ray->x())) continue;
          // With blur, sub-sample k of pixel (u, v) is taken at instant (k + u + v) mod n² (decorrelates time
          // from sub-pixel position); without blur there is a single pose.
          const auto p = static_cast<std::size_t>(m == 1 ? 0 : (k + u + v) % m);
          const Vector3f d = frame.R_WC[p] * Vector3f(ray->x(), ray->y(), 1.0f);
          for (int i = 0; i < 3; ++i) {
            scratch.o[i][n] = frame.p_WC[p][i];
            scratch.d[i][n] = d[i];
          }
          ++n;
        }
    }
    const World::Rays rays{{scratch.o[0].data(), scratch.o[1].data(), scratch.o[2].data()},
                           {scratch.d[0].data(), scratch.d[1].data(), scratch.d[2].data()},
                           n};
    world_.trace(rays, boxes, scratch.grey.data());
    const float* grey = scratch.grey.data();
    if (vectorized && (n2_ == 1 || n2_ == 4) && tile_full_[static_cast<std::size_t>(tile_row * tiles_x_ + tx)] != 0) {
      // Every ray valid: the grey levels are the pixels' sub-samples in order, summed eight pixels at a time.
      for (int v = v_begin; v < v_end; ++v, grey += static_cast<std::size_t>((u_end - u_begin) * n2_))
        average_subsamples_avx2(grey, u_end - u_begin, n2_, inv_n2,
                                sums.data() + static_cast<std::size_t>(v - v_begin) * static_cast<std::size_t>(width_) +
                                    static_cast<std::size_t>(u_begin));
      continue;
    }
    for (int v = v_begin; v < v_end; ++v) {
      const Eigen::Vector2f* ray = rays_.data() + (static_cast<std::size_t>(v) * static_cast<std::size_t>(width_) +
                                                   static_cast<std::size_t>(u_begin)) * static_cast<std::size_t>(n2_);
      float* sum_row = sums.data() + static_cast<std::size_t>(v - v_begin) * static_cast<std::size_t>(width_);
      for (int u = u_begin; u < u_end; ++u) {
        float sum = 0.0f;
        for (int k = 0; k < n2_; ++k, ++ray)
          if (!std::isnan(ray->x())) sum += *grey++;
        sum_row[u] = sum * inv_n2;
      }
    }
  }
  const bool noisy = options_.noise_std > 0.0;
  for (int v = v_begin; v < v_end; ++v) {
    RowNoise noise(noise_seed ^ (0x9E3779B97F4A7C15ULL * static_cast<std::uint64_t>(v + 1)),
                   static_cast<float>(options_.noise_std));
    std::uint8_t* row = out.ptr<std::uint8_t>(v);
    float* sum_row = sums.data() + static_cast<std::size_t>(v - v_begin) * static_cast<std::size_t>(width_);
    if (vectorized) {  // the row's noise drawn first (the same stream), then added, clamped and rounded in vector
      if (noisy)
        for (int u = 0; u < width_; ++u) sum_row[u] += noise();
      quantize_row_avx2(sum_row, width_, row);
      continue;
    }
    for (int u = 0; u < width_; ++u) {
      float value = sum_row[u];
      if (noisy) value += noise();
      // Round half away from zero (as std::lround) after clamping to [0, 255].
      value = std::clamp(value, 0.0f, 255.0f);
      const int whole = static_cast<int>(value);
      row[u] = static_cast<std::uint8_t>(whole + (value - static_cast<float>(whole) >= 0.5f ? 1 : 0));
    }
  }
}

cv::Mat Renderer::render(const std::vector<math::Pose>& T_WC, std::uint64_t noise_seed) const {
  if (static_cast<int>(T_WC.size()) != pose_count())
    throw DataError(fmt::format("render: {} camera poses given, {} expected", T_WC.size(), pose_count()));
  constexpr float kInf = std::numeric_limits<float>::infinity();
  // Margin on the projected rectangles (normalised coordinates, ~0.5 px): covers the float rounding of the rays.
  constexpr double kMargin = 1e-3;
  Frame frame;
  for (const math::Pose& T : T_WC) {
    frame.R_WC.push_back(T.q.toRotationMatrix().cast<float>());
    frame.p_WC.push_back(T.p.cast<float>());
  }
  const std::vector<Aabb>& obstacles = world_.boxes();
  frame.boxes.assign(obstacles.size(), Rect{kInf, -kInf, kInf, -kInf});
  for (std::size_t k = 0; k < obstacles.size(); ++k) {
    Rect& r = frame.boxes[k];
    for (const math::Pose& T : T_WC) {
      const Eigen::Matrix3d R_CW = T.q.toRotationMatrix().transpose();
      int in_front = 0;
      double x_min = kInf, x_max = -kInf, y_min = kInf, y_max = -kInf;
      for (int c = 0; c < 8; ++c) {
        const Eigen::Vector3d p_W((c & 1 ? obstacles[k].hi : obstacles[k].lo).x(),
                                  (c & 2 ? obstacles[k].hi : obstacles[k].lo).y(),
                                  (c & 4 ? obstacles[k].hi : obstacles[k].lo).z());
        const Eigen::Vector3d p_C = R_CW * (p_W - T.p);
        if (p_C.z() <= 1e-6) continue;
        ++in_front;
        x_min = std::min(x_min, p_C.x() / p_C.z());
        x_max = std::max(x_max, p_C.x() / p_C.z());
        y_min = std::min(y_min, p_C.y() / p_C.z());
        y_max = std::max(y_max, p_C.y() / p_C.z());
      }
      if (in_front == 0) continue;  // wholly behind the camera
      if (in_front < 8) {           // across the camera plane: its projection is unbounded
        r = Rect{-kInf, kInf, -kInf, kInf};
        break;
      }
      r.x_min = std::min(r.x_min, static_cast<float>(x_min - kMargin));
      r.x_max = std::max(r.x_max, static_cast<float>(x_max + kMargin));
      r.y_min = std::min(r.y_min, static_cast<float>(y_min - kMargin));
      r.y_max = std::max(r.y_max, static_cast<float>(y_max + kMargin));
    }
  }
  cv::Mat out(height_, width_, CV_8UC1);
  const int threads = options_.threads;
  std::vector<std::thread> pool;
  // Interleaved blocks of kTile rows balance the load (floor/ceiling rows cost the same as wall rows, but boxes
  // don't).
  auto work = [&](int k) {
    Scratch scratch;
    scratch.sums.resize(static_cast<std::size_t>(kTile) * static_cast<std::size_t>(width_));
    scratch.boxes.reserve(obstacles.size());
    const auto tile_rays = static_cast<std::size_t>(kTile * kTile * n2_);
    for (int i = 0; i < 3; ++i) {
      scratch.o[i].resize(tile_rays);
      scratch.d[i].resize(tile_rays);
    }
    scratch.grey.resize(tile_rays);
    for (int tile_row = k; tile_row < tiles_y_; tile_row += threads)
      render_block(frame, noise_seed, tile_row, scratch, out);
  };
  for (int k = 1; k < threads; ++k) pool.emplace_back(work, k);
  work(0);
  for (auto& t : pool) t.join();
  return out;
}

}  // namespace rtslam::sim
