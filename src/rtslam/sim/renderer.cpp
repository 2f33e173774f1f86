#include "rtslam/sim/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <thread>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"
#include "rtslam/core/yaml.hpp"

namespace rtslam::sim {

using Eigen::Vector3f;

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
               Vector3f::Zero());
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
            if (camera.unproject(px, ray)) rays_[idx] = ray.cast<float>();
          }
  };
  std::vector<std::thread> pool;
  for (int k = 1; k < options_.threads; ++k) pool.emplace_back(fill, k, options_.threads);
  fill(0, options_.threads);
  for (auto& t : pool) t.join();
  for (const Vector3f& r : rays_) valid_rays_ += r.z() > 0.0f ? 1 : 0;
}

int Renderer::pose_count() const { return options_.motion_blur ? n2_ : 1; }

std::vector<double> Renderer::pose_time_offsets() const {
  const int m = pose_count();
  std::vector<double> out(static_cast<std::size_t>(m), 0.0);
  if (m > 1)
    for (int k = 0; k < m; ++k) out[static_cast<std::size_t>(k)] = options_.exposure_s * ((k + 0.5) / m - 0.5);
  return out;
}

void Renderer::render_rows(const std::vector<math::Pose>& T_WC, std::uint64_t noise_seed, int row_begin,
                           int row_step, cv::Mat& out) const {
  const int m = static_cast<int>(T_WC.size());
  std::vector<Eigen::Matrix3f> R(static_cast<std::size_t>(m));
  std::vector<Vector3f> o(static_cast<std::size_t>(m));
  for (int k = 0; k < m; ++k) {
    R[static_cast<std::size_t>(k)] = T_WC[static_cast<std::size_t>(k)].q.toRotationMatrix().cast<float>();
    o[static_cast<std::size_t>(k)] = T_WC[static_cast<std::size_t>(k)].p.cast<float>();
  }
  const float inv_n2 = 1.0f / static_cast<float>(n2_);
  const bool noisy = options_.noise_std > 0.0;
  Hit hit;
  for (int v = row_begin; v < height_; v += row_step) {
    Rng rng(noise_seed ^ (0x9E3779B97F4A7C15ULL * static_cast<std::uint64_t>(v + 1)));
    std::normal_distribution<float> normal(0.0f, static_cast<float>(options_.noise_std));
    std::uint8_t* row = out.ptr<std::uint8_t>(v);
    const Vector3f* ray = rays_.data() + static_cast<std::size_t>(v) * static_cast<std::size_t>(width_) *
                                             static_cast<std::size_t>(n2_);
    for (int u = 0; u < width_; ++u) {
      float sum = 0.0f;
      for (int k = 0; k < n2_; ++k, ++ray) {
        if (ray->z() <= 0.0f) continue;
        // With blur, sub-sample k of pixel (u, v) is taken at instant (k + u + v) mod n² (decorrelates time from
        // sub-pixel position); without blur there is a single pose.
        const int p = m == 1 ? 0 : (k + u + v) % m;
        const Vector3f d = R[static_cast<std::size_t>(p)] * (*ray);
        if (world_.cast(o[static_cast<std::size_t>(p)], d, hit))
          sum += world_.shade(hit.face, o[static_cast<std::size_t>(p)] + hit.t * d);
      }
      float value = sum * inv_n2;
      if (noisy) value += normal(rng);
      row[u] = static_cast<std::uint8_t>(std::clamp(std::lround(value), 0L, 255L));
    }
  }
}

cv::Mat Renderer::render(const std::vector<math::Pose>& T_WC, std::uint64_t noise_seed) const {
  if (static_cast<int>(T_WC.size()) != pose_count())
    throw DataError(fmt::format("render: {} camera poses given, {} expected", T_WC.size(), pose_count()));
  cv::Mat out(height_, width_, CV_8UC1);
  const int threads = options_.threads;
  std::vector<std::thread> pool;
  // Interleaved blocks of 8 rows balance the load (floor/ceiling rows cost the same as wall rows, but boxes don't).
  auto work = [&](int k) {
    for (int block = k; block * 8 < height_; block += threads)
      for (int v = block * 8; v < std::min(height_, block * 8 + 8); ++v) render_rows(T_WC, noise_seed, v, height_, out);
  };
  for (int k = 1; k < threads; ++k) pool.emplace_back(work, k);
  work(0);
  for (auto& t : pool) t.join();
  return out;
}

}  // namespace rtslam::sim
