#pragma once
// Helpers of the viz tests: synthetic reports and pixel checks on drawn overlays.
#include <cmath>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "rtslam/viz/overlay.hpp"
#include "rtslam/viz/report.hpp"

namespace rtslam::viz::test {

/// S = R(angle) diag(sx², sy²) R(angle)ᵀ: semi-axes sx (along angle) and sy, in px.
inline Eigen::Matrix2d covariance(double sx, double sy, double angle_rad) {
  const Eigen::Matrix2d R = Eigen::Rotation2Dd(angle_rad).toRotationMatrix();
  return R * Eigen::Vector2d(sx * sx, sy * sy).asDiagonal() * R.transpose();
}

/// A black camera-size image report with the given matches (camera 320x240 by default).
inline FrameReport blank_report(int width = 320, int height = 240) {
  FrameReport r;
  r.index = 7;
  r.t = 1'234'000'000;
  r.camera = CameraInfo{width, height, 200.0, 200.0, width / 2.0, height / 2.0};
  r.image = cv::Mat::zeros(height, width, CV_8UC1);
  return r;
}

/// Whether a pixel within `radius` of p looks like `colour` drawn anti-aliased on black (α·colour, α >= 0.45).
inline bool colour_near(const cv::Mat& bgr, const Eigen::Vector2d& p, const cv::Scalar& colour, double radius = 1.5) {
  const Eigen::Vector3d c(colour[0], colour[1], colour[2]);
  for (int dy = -2; dy <= 2; ++dy) {
    for (int dx = -2; dx <= 2; ++dx) {
      const int u = static_cast<int>(std::lround(p.x())) + dx, v = static_cast<int>(std::lround(p.y())) + dy;
      if (u < 0 || v < 0 || u >= bgr.cols || v >= bgr.rows) continue;
      if (Eigen::Vector2d(u - p.x(), v - p.y()).norm() > radius + 0.75) continue;
      const cv::Vec3b px = bgr.at<cv::Vec3b>(v, u);
      const Eigen::Vector3d q(px[0], px[1], px[2]);
      const double alpha = q.dot(c) / c.dot(c);
      if (alpha >= 0.45 && (q - alpha * c).norm() < 45.0) return true;
    }
  }
  return false;
}

/// Whether the pixel at p is black (nothing drawn).
inline bool black_at(const cv::Mat& bgr, const Eigen::Vector2d& p) {
  const cv::Vec3b px = bgr.at<cv::Vec3b>(static_cast<int>(std::lround(p.y())), static_cast<int>(std::lround(p.x())));
  return px[0] == 0 && px[1] == 0 && px[2] == 0;
}

}  // namespace rtslam::viz::test
