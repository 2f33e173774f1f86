#pragma once
// viz::FrameReport: plain data of one processed image, made on the filter thread and handed to the viewer, the
// overlay writer and the video writer (viewer.hpp, overlay.hpp). Wiring, in run_image_slam's observer:
//
//   const viz::FrameReport r = viz::make_report(frame, image, &stats);  // frame: pipeline::ImageSlamFrame
//   viewer.push(r);  overlays.write(r);  video.write(r);
//
// make_report copies what it needs (the robot and camera poses with the pose covariance, every landmark's position
// and 3x3 position covariance in W, the data manager's FrameMatch list) and shares the grey image (cv::Mat reference
// counting: no pixel copy; an image over foreign memory is copied), so the report outlives the frame, can go to
// another thread, and is cheap to copy. It costs O(landmarks) small matrix products: measured in docs/viewer.md.
// Everything else (drawing, encoding, JSON) happens on the consumer's side.
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "rtslam/core/time.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/strategies/active_search.hpp"
#include "rtslam/strategies/init_grid.hpp"

namespace rtslam::viz {

using FrameMatch = strategies::ActiveSearchDataManager::FrameMatch;

/// One landmark of the map at the frame's time.
struct LandmarkReport {
  int id = -1;
  bool euclidean = false;                            // false: AHP (anchored homogeneous point)
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();     // position in W (m)
  Eigen::Matrix3d cov_W = Eigen::Matrix3d::Zero();   // position covariance in W (m²); AHP: J_p_L P_L J_p_Lᵀ
  bool created_now = false;                          // initialized in this frame
  std::optional<Eigen::Vector2d> z0_px;              // created_now: the pixel it was initialized at
};

/// A cell of the feature-initialization grid (strategies::InitGrid) in this frame.
struct GridCell {
  Eigen::Vector4d rect_px = Eigen::Vector4d::Zero();  // [x0 y0 x1 y1), pixels
  bool occupied = false;                              // holds an observation: no initialization there
};

/// Pinhole parameters of the camera, for the 3D view's frustum (distortion ignored there).
struct CameraInfo {
  int width = 0, height = 0;             // px
  double fx = 0, fy = 0, cx = 0, cy = 0;  // px
};

struct FrameReport {
  int index = 0;    // processed images before this one
  TimeNs t = 0;     // image time (in the filter's clock)
  cv::Mat image;    // CV_8UC1 (empty: none); shares the caller's pixels (see make_report): never write into it
  math::Pose T_WR;  // robot pose
  Eigen::Matrix<double, 6, 6> cov_pose = Eigen::Matrix<double, 6, 6>::Zero();  // [δp δθ] of T_WR (filter convention)
  math::Pose T_WS;  // camera pose (T_WR T_RS)
  CameraInfo camera;
  std::vector<LandmarkReport> landmarks;  // the whole map
  std::vector<FrameMatch> matches;        // every visible observation (FrameMatch: h, S, z and its fate)
  std::vector<GridCell> grid;             // empty when the caller gave no grid
  // Counts from `matches` (always filled) and the frame's stage timings (when `has_timing`).
  slam::FrameStats stats;
  bool has_timing = false;
};

/// The report of one image. `map` must hold a robot with a sensor (the first of each is used); `matches` is the data
/// manager's list for this image; `grey` (CV_8UC1, may be empty) is shared when it owns its pixels — the caller
/// must not write into them afterwards (rtslam's sources give every image its own cv::Mat) — and copied when it
/// wraps foreign memory; `stats` (optional) gives the stage timings and counts; `grid` (optional) the init grid's
/// cells. Never throws on the per-frame path.
FrameReport make_report(int index, TimeNs t, const slam::Map& map, const std::vector<FrameMatch>& matches,
                        const cv::Mat& grey, const slam::FrameStats* stats = nullptr,
                        const strategies::InitGrid* grid = nullptr);

/// The same from the observer's argument of pipeline::run_image_slam (a pipeline::ImageSlamFrame: index, t, map,
/// matches). A template so that viz does not depend on pipeline (which may draw with viz).
template <class ImageSlamFrame>
FrameReport make_report(const ImageSlamFrame& frame, const cv::Mat& grey, const slam::FrameStats* stats = nullptr,
                        const strategies::InitGrid* grid = nullptr) {
  return make_report(frame.index, frame.t, *frame.map, *frame.matches, grey, stats, grid);
}

/// Normalized innovation squared of the updated observations of a frame, measured against their first
/// prediction: Σ (z − h)ᵀ S⁻¹ (z − h) over `count` observations (each 2 dof).
struct Nis {
  double sum = 0.0;
  int count = 0;
};
Nis frame_nis(const std::vector<FrameMatch>& matches);

}  // namespace rtslam::viz
