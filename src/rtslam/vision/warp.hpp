#pragma once
// Appearance prediction (paper, "Image processing"; MATH.md): the patch a landmark is expected to show in the
// current view, warped from its initial patch (tracking against the initial appearance, not the last one).
//
// The patch is modelled as a plane through the landmark p, fronto-parallel to the initial view C0: normal n = the
// unit viewing ray of p in C0, at distance d0 = |p_C0|. With T_C1C0 = (R, t) between the views the plane induces,
// on undistorted pinhole pixels, x1 ~ H x0 with H = K (R + t nᵀ / d0) K⁻¹. Every pixel of the predicted patch is
// mapped back through H⁻¹ into the initial patch and sampled bilinearly.
// Independent of the filter and of camera-model classes: poses, intrinsics and the point are plain values.
// Poses are T_WC (camera C into world W: p_W = R_WC p_C + t_WC); C is the optical frame (x right, y down, z ahead).
// Pixel convention: see image.hpp.
#include <Eigen/Core>

#include "rtslam/vision/image.hpp"

namespace rtslam::vision {

struct PinholeIntrinsics {
  double fx = 1.0;
  double fy = 1.0;
  double cx = 0.0;
  double cy = 0.0;
};

struct RigidPose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
};

/// Optional local affine model of lens distortion around the landmark, when the images are distorted: the patches
/// then live in distorted pixels, and an undistorted offset δu maps to the distorted offset J_dist_undist δu.
struct LocalDistortion {
  Eigen::Vector2d centre0_dist_px = Eigen::Vector2d::Zero();  // distorted pixel of the landmark in view 0
  Eigen::Matrix2d J_dist_undist_0 = Eigen::Matrix2d::Identity();  // at the landmark's pixel in view 0
  Eigen::Matrix2d J_dist_undist = Eigen::Matrix2d::Identity();    // at its predicted pixel in the current view
};

struct WarpResult {
  bool ok = false;                                      // false: point behind a camera or degenerate warp
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();  // undistorted pixel of p in the current view
  int n_outside = 0;  // predicted pixels whose source fell outside the initial patch (border value used)
};

/// The pixel homography H_1_0 (x1 ~ H x0) induced by the plane through p_W fronto-parallel to view 0. False if p
/// is not in front of both cameras.
bool plane_homography(const PinholeIntrinsics& K, const RigidPose& T_WC0, const RigidPose& T_WC1,
                      const Eigen::Vector3d& p_W, Eigen::Matrix3d* H_1_0);

/// Bilinear sample of `image` at (u, v) (image.hpp convention), coordinates clamped to the image.
double sample_bilinear(ImageView image, double u, double v);

/// Fills `out` (odd square, e.g. 15x15) with the predicted appearance of the landmark p_W in the current view T_WC.
/// `init_patch` (odd square, e.g. 31x31) was taken from view T_WC0 and its centre pixel lies at `init_centre_px` of
/// that image (undistorted pixels, or distorted ones with `distortion`). The centre pixel of `out` corresponds to
/// the landmark's pixel in the current view, so ZNCC positions of `out` are landmark positions. Allocation-free.
WarpResult predict_appearance(ImageView init_patch, const Eigen::Vector2d& init_centre_px,
                              const PinholeIntrinsics& K, const RigidPose& T_WC0, const RigidPose& T_WC,
                              const Eigen::Vector3d& p_W, MutableImageView out,
                              const LocalDistortion* distortion = nullptr);

}  // namespace rtslam::vision
