#pragma once
// Pinhole camera with lens distortion: projection, unprojection and their analytic Jacobians.
//
// Frames: C is the camera's optical frame (z forward, x right, y down). Pixels (u, v) with (0, 0) the centre of the
// top-left pixel. Normalized undistorted coordinates (x, y) = (X/Z, Y/Z); distortion maps them to normalized
// distorted coordinates (x_d, y_d), and u = fx x_d + cx, v = fy y_d + cy (../shared/MATH.md, "Cameras").
//
// Distortion models (r² = x² + y²):
// - None:        x_d = x.
// - RadTan:      (EuRoC/Kalibr `radial-tangential`, OpenCV's k1 k2 p1 p2 [k3]) k = 1 + k1 r² + k2 r⁴ + k3 r⁶,
//                x_d = k x + 2 p1 x y + p2 (r² + 2 x²), y_d = k y + p1 (r² + 2 y²) + 2 p2 x y.
// - Equidistant: (Kalibr `equidistant`) θ = atan(r), θ_d = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸),
//                (x_d, y_d) = (θ_d / r) (x, y).
// - MonoSlam:    Davison's one-parameter model on PIXEL radii about (cx, cy): with (du, dv) = (fx x, fy y),
//                r_u = |(du, dv)|, the distorted offset is (du, dv) / sqrt(1 + 2 κ r_u²); inverse
//                r_u = r_d / sqrt(1 − 2 κ r_d²). κ in px⁻² (MonoSLAM: 9e-6).
// - RtslamPoly:  RT-SLAM's radial polynomial (x_d, y_d) = d(r²) (x, y), d = 1 + d0 r² + d1 r⁴ + ...; the inverse
//                uses a correction polynomial (x, y) = c(r_d²) (x_d, y_d), c = 1 + c0 r_d² + c1 r_d⁴ + ...,
//                least-squares fitted at construction over the image's radii, then refined by Newton.
//
// Valid domain: the radial part of each distortion must be strictly increasing in the radius (beyond its first
// turning point the mapping folds back and is not invertible); the largest valid radius is computed at
// construction. MonoSlam with κ < 0 additionally needs 1 + 2 κ r_u² > 0, and its inverse 1 − 2 κ r_d² > 0.
// Projection also needs Z > kMinDepth·|p_C| (in front of the camera, not grazing).
// Jacobians are optional output pointers (nullptr: not computed), named J_out_in. The hot path never throws:
// invalid inputs are reported by the boolean return value.
#include <string>
#include <vector>

#include <Eigen/Core>

namespace rtslam::models {

enum class DistortionModel { None, RadTan, Equidistant, MonoSlam, RtslamPoly };

/// Name of a model as used in configuration files: "none", "radial-tangential", "equidistant", "monoslam",
/// "rtslam-poly".
std::string to_string(DistortionModel model);
/// Parses the names above (plus Kalibr/OpenCV aliases "radtan", "pinhole-radtan", "fisheye", "poly");
/// throws ConfigError naming the value otherwise.
DistortionModel distortion_model_from_string(const std::string& name);

struct CameraIntrinsics {
  int width = 0, height = 0;              // pixels
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels
  DistortionModel model = DistortionModel::None;
  std::vector<double> coeffs;  // RadTan: k1 k2 p1 p2 [k3]; Equidistant: k1..k4; MonoSlam: kappa [px^-2];
                               // RtslamPoly: d0 d1 ... (radial polynomial in normalized coords)
  /// Throws ConfigError naming the bad value (image size and focal lengths > 0, finite centre, the number of
  /// coefficients the model takes, finite coefficients).
  void validate() const;
};

class PinholeCamera {
 public:
  /// Projection needs Z > kMinDepth · |p_C|: at most ~89.99994° off the optical axis.
  static constexpr double kMinDepth = 1e-6;
  /// Unprojection converges when the reprojection residual is below this many pixels.
  static constexpr double kUnprojectTolerancePx = 1e-10;

  /// Validates the intrinsics (ConfigError) and precomputes the valid domain and, for RtslamPoly, the
  /// correction polynomial.
  explicit PinholeCamera(CameraIntrinsics intr);

  const CameraIntrinsics& intrinsics() const { return intr_; }

  /// Point in the camera frame C (z forward, x right, y down) -> distorted pixel. Valid iff z > eps and the
  /// distortion is inside its valid domain (NOT checking image bounds). J_px_pC is 2x3.
  bool project(const Eigen::Vector3d& p_C, Eigen::Vector2d& px, Eigen::Matrix<double, 2, 3>* J_px_pC = nullptr) const;

  /// Pixel inside [margin, width-1-margin] x [margin, height-1-margin].
  bool in_image(const Eigen::Vector2d& px, double margin = 0.0) const;

  /// Distorted pixel -> ray in C with z = 1 (undistorted normalized coords); J_ray_px is 3x2 (third row zero).
  /// Iterative (Newton) where needed, converging to 1e-10 px; returns false if it does not converge, or if the
  /// pixel has no preimage in the valid domain (e.g. a fisheye pixel seen at 90° or more off axis).
  bool unproject(const Eigen::Vector2d& px, Eigen::Vector3d& ray_C,
                 Eigen::Matrix<double, 3, 2>* J_ray_px = nullptr) const;

  /// Normalized undistorted (x, y) -> normalized distorted (x_d, y_d); J = ∂xy_d/∂xy. False outside the domain.
  bool distort(const Eigen::Vector2d& xy, Eigen::Vector2d& xy_d, Eigen::Matrix2d* J = nullptr) const;
  /// Normalized distorted -> normalized undistorted; J = ∂xy/∂xy_d (the inverse of distort's Jacobian).
  /// Closed form for None and MonoSlam, Newton otherwise (residual below kUnprojectTolerancePx in pixels).
  bool undistort(const Eigen::Vector2d& xy_d, Eigen::Vector2d& xy, Eigen::Matrix2d* J = nullptr) const;

  /// Largest valid undistorted normalized radius (infinity when the distortion is monotonic everywhere).
  double max_radius() const { return r_max_; }
  /// RtslamPoly: the fitted correction coefficients c0 c1 ... (empty for other models).
  const std::vector<double>& correction_coeffs() const { return correction_; }
  /// RtslamPoly: the closed-form inverse by the correction polynomial alone (no Newton refinement), as RT-SLAM
  /// used it. For other models returns xy_d unchanged.
  Eigen::Vector2d undistort_by_correction(const Eigen::Vector2d& xy_d) const;

 private:
  void compute_domain();
  void fit_correction();

  CameraIntrinsics intr_;
  double r_max_ = 0.0;              // largest valid undistorted normalized radius
  double rd_max_ = 0.0;             // Equidistant, RtslamPoly: the distorted radius reached at r_max_ (or at 90°)
  std::vector<double> correction_;  // RtslamPoly correction polynomial coefficients
};

}  // namespace rtslam::models
