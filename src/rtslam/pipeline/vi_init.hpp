#pragma once
// Visual-inertial start of the inertial robot from a short window of images and IMU samples, without ground truth
// (issue "Inertial SLAM that holds on real IMU data": start anywhere, at rest or in motion, at 400 deg/s and 3 g).
//
// Why: the filter alone, started with broad priors, must take the velocity's scale from the inverse-depth priors of
// its first landmarks, whose error is common to all of them; a start in fast motion then runs several centimetres
// off for the first second (7 cm on the high-dynamic sequence), and the IMU alone cannot tell vibration at rest from
// slow motion. The window's images settle both, in the way of the closed-form dynamic initializers of Martinelli
// (2014), Kaiser et al. (2017) and OpenVINS:
//  1. features: the best Harris corner of each empty cell of a grid, tracked image to image by ZNCC around the
//     position the gyro's rotation predicts (the patch of the previous image as the template); a track may begin in
//     any image and end where its feature leaves the view (at 400 deg/s and 50 Hz a corner crosses the image in about
//     ten images: no feature lasts a whole window), and cells the motion empties are refilled; a feature counts when
//     tracked over min_track_frames images (OpenVINS' dynamic initializer likewise asks a number of measurements per
//     feature, not the whole window);
//  2. standstill: when the tracked features move less than standstill_max_disparity_px over the window, the robot
//     is at rest whatever the IMU's vibration says: v = 0, gyro bias = the mean gyro, gravity = −the mean specific
//     force;
//  3. otherwise a linear least-squares problem: with the IMU preintegrated from the first image (ΔR_i, α_i: rotation
//     and double-integrated specific force, gravity and initial velocity left out), the position of R_i in R_0 is
//     v₀ t_i + ½ g t_i² + α_i, and each tracked bearing b of feature f in image i gives
//     [b]× (R_SR ΔR_iᵀ (p_f − v₀ t_i − ½ g t_i² − α_i) + t_SR) = 0, linear in the unknowns p_f (feature positions in
//     R_0), v₀ and g (in R_0). The features are eliminated (Schur complement), g is solved on the sphere |g| = gravity
//     (a trust-region subproblem: (NᵀN + λI) g = Nᵀd with λ chosen so that |g| = gravity), then v₀ and the p_f;
//     the solution is accepted when enough features lie in front of the cameras, the reprojection RMS is small, the
//     accelerations displaced the body enough for the scale to be observable (min_excitation_m). The gyro bias is
//     estimated first (Gauss-Newton on the window's algebraic residuals): real IMUs carry several deg/s.
//  4. the linear solution starts a robust Levenberg-Marquardt on the pixel errors over v₀, g (on its sphere), the
//     accelerometer bias (with its prior), the gyro bias and the features (Schur complement), as OpenVINS and
//     VINS-Mono refine theirs; at 400 deg/s the algebraic errors tilt gravity by 10-20 deg where the pixel errors say
//     1 deg. The whole window and its first and last two thirds are refined apart (the parts with the whole window's
//     gyro bias) and must agree on v₀ and g. Without enough parallax or excitation, or when the parts disagree, the
//     caller lets the window grow (up to max_window_s); slow motions need longer windows than fast ones.
// The result gives the filter its start at the first image: velocity and gravity with their least-squares
// uncertainty, and the median depth of the features, which becomes the inverse-depth prior of the first landmarks.
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "rtslam/core/yaml.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/models/sensors/pinhole_camera.hpp"
#include "rtslam/pipeline/inertial_init.hpp"

namespace rtslam::pipeline {

struct ViInitFrame {
  TimeNs t = 0;   // in the IMU clock
  cv::Mat image;  // CV_8UC1
};

struct ViInitResult {
  enum class Kind { Standstill, Dynamic, Failed };
  Kind kind = Kind::Failed;
  std::string reason;                              // why it failed, or a summary
  Eigen::Vector3d v0_R = Eigen::Vector3d::Zero();  // velocity at the first image, in R_0
  Eigen::Vector3d g_R = Eigen::Vector3d::Zero();   // gravity in R_0
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_bias = Eigen::Vector3d::Zero();  // refined with the prior accel_bias_std (Dynamic)
  Eigen::Matrix<double, 6, 6> cov_v_g = Eigen::Matrix<double, 6, 6>::Zero();  // [v₀ g] least-squares covariance
  Eigen::Matrix3d cov_gyro_bias = Eigen::Matrix3d::Zero();                    // its gyro bias's (Dynamic)
  double median_depth_m = 0.0;  // features' depth in camera 0 at the first image (Dynamic)
  int features = 0;             // tracked over min_track_frames images or more
  int tracks_left_view = 0;     // tracks ended because the gyro predicted them out of the image
  int tracks_unmatched = 0;     // tracks ended because ZNCC found no match in the search box
  int frames = 0;
  double disparity_px = 0.0;  // median feature displacement over the window
  double parallax_px = 0.0;   // the same after removing the gyro's rotation
  double reprojection_px = 0.0;
  double excitation_m = 0.0;         // displacement due to the accelerations over the window
  bool needs_longer_window = false;  // failed for lack of parallax or excitation
  std::string describe() const;
};

/// The filter's start from a successful result, at the window's first image: the gravity-aligned frame of
/// initialize_inertial (attitude from −g), v₀ and g with their least-squares uncertainty (3σ, floored), the solved
/// biases with the configured priors (the gyro bias's widened to its 3σ when that is broader); at rest as initialize_inertial's standstill (v = 0, gyro bias = mean gyro).
InertialStart inertial_start_from_vi(const ViInitResult& r, const InertialOptions& o);

/// Runs the start on the window's images (time-ordered, the first at t_0) and the IMU samples covering them. The
/// gyro bias is estimated with the motion, and taken as the mean gyro at rest.
ViInitResult initialize_visual_inertial(const std::vector<ViInitFrame>& frames, const std::vector<ImuWindowSample>& imu,
                                        const models::PinholeCamera& camera, const math::Pose& T_RS,
                                        const ViInitOptions& options);

}  // namespace rtslam::pipeline
