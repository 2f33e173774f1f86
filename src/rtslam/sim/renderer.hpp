#pragma once
// Camera image rendering by ray casting, with the exact rays of the calibrated (distorted) camera model.
//
// For every pixel (u, v) (integer coordinates = pixel centres, as in models::PinholeCamera) and every sub-sample
// (u + (i + ½)/n − ½, v + (j + ½)/n − ½), i, j < n = supersampling, the ray is PinholeCamera::unproject of that
// sub-pixel (Newton, 1e-10 px), precomputed once per camera in a ray table. Per frame: rotate each ray into W,
// find the closest surface (World::cast), sample its texture bilinearly, average the n² sub-samples (box filter
// anti-aliasing), add seeded Gaussian noise (grey levels) and round to 8 bits.
// Motion blur (optional): the n² sub-samples of a pixel are taken at n² distinct instants spread over the
// exposure (the caller passes one camera pose per instant), so blur costs nothing extra.
// Rendering is split over `threads` threads by rows; the result does not depend on the thread count (noise is
// drawn per row from a splitmix64 stream seeded by (frame seed, row), Gaussian by the Marsaglia polar method).
// Culling: the image is cut into tiles of kTile x kTile pixels whose rays span a known rectangle of the z = 1
// plane (precomputed). Per frame, each obstacle's corners are projected (every pose); a tile's rays are only
// tested against the obstacles whose projected bounding rectangle meets the tile's (conservative, with margin:
// the picture is the same as testing every obstacle).
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "rtslam/math/rotation.hpp"
#include "rtslam/models/sensors/pinhole_camera.hpp"
#include "rtslam/sim/world.hpp"

namespace rtslam::sim {

struct RenderOptions {
  int supersampling = 2;       // n: n x n sub-samples per pixel
  double noise_std = 2.0;      // grey levels (0 = none)
  bool motion_blur = false;
  double exposure_s = 0.005;   // shutter time for motion blur
  int threads = 2;
};

class Renderer {
 public:
  /// Precomputes the ray table (unprojects width·height·n² sub-pixels). Throws ConfigError on bad options.
  Renderer(const World& world, const models::PinholeCamera& camera, const RenderOptions& options);

  /// Number of camera poses render() takes: n² with motion blur, else 1.
  int pose_count() const;
  /// Offsets (s, relative to the image timestamp) of the poses render() takes, spread evenly over
  /// [−exposure/2, +exposure/2] with blur, {0} without.
  std::vector<double> pose_time_offsets() const;

  /// Renders with camera poses T_WC (one per pose_count()). `noise_seed` draws the pixel noise.
  cv::Mat render(const std::vector<math::Pose>& T_WC, std::uint64_t noise_seed) const;
  cv::Mat render(const math::Pose& T_WC, std::uint64_t noise_seed) const {
    return render(std::vector<math::Pose>(static_cast<std::size_t>(pose_count()), T_WC), noise_seed);
  }

  const RenderOptions& options() const { return options_; }
  /// Sub-pixel rays with a preimage (pixels without one — outside a fisheye's domain — render black).
  std::size_t valid_rays() const { return valid_rays_; }

 private:
  static constexpr int kTile = 8;  // pixels; also the row block of the thread split
  struct Rect {  // on the z = 1 plane of the camera (normalised coordinates)
    float x_min, x_max, y_min, y_max;
  };
  struct Frame;    // per-frame poses and obstacle rectangles
  struct Scratch;  // per-thread buffers
  void render_block(const Frame& frame, std::uint64_t noise_seed, int tile_row, Scratch& scratch, cv::Mat& out) const;
  static int rotate_rays_avx2(const float* xy, int count, const Eigen::Matrix3f& R, Scratch& scratch, std::size_t n);
  static void average_subsamples_avx2(const float* grey, int pixels, int n2, float inv_n2, float* out);
  static void quantize_row_avx2(const float* value, int width, std::uint8_t* row);

  const World& world_;
  RenderOptions options_;
  int width_ = 0, height_ = 0, n2_ = 1;
  // [(v * width + u) * n2 + k]: (x, y) of the camera-frame ray (x, y, 1), NaN if invalid; z is not stored, as the
  // table is read once per frame (11.6 MB instead of 17.3 at 752x480, n = 2).
  std::vector<Eigen::Vector2f> rays_;
  std::size_t valid_rays_ = 0;
  int tiles_x_ = 0, tiles_y_ = 0;
  std::vector<Rect> tile_rays_;  // [ty * tiles_x + tx]: bounds of the tile's valid rays (empty: x_min > x_max)
  std::vector<std::uint8_t> tile_full_;  // [ty * tiles_x + tx]: 1 if every ray of the tile is valid
};

}  // namespace rtslam::sim
