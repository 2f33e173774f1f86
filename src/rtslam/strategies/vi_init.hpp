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

#include "rtslam/core/yaml.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/models/sensors/pinhole_camera.hpp"
#include "rtslam/strategies/inertial_start.hpp"
#include "rtslam/vision/image.hpp"

namespace rtslam::strategies {

struct ViInitOptions {
  bool enabled = true;
  double window_s = 0.4;                      // images used: the first window_s seconds ...
  double max_window_s = 2.0;                  // ... growing up to this while parallax or excitation lack
  double min_excitation_m = 0.1;              // m: displacement the accelerations must cause over the window
  double max_wait_s = 1.0;                    // s of failed windows before the IMU-only start takes over
  int min_frames = 5;
  int min_track_frames = 5;                   // images a feature must be tracked over (not the whole window)
  int cells_x = 8, cells_y = 5;               // feature grid (one Harris corner per cell)
  int patch_size = 15;                        // ZNCC template (odd)
  double min_score = 0.8;                     // ZNCC acceptance
  double search_px = 40.0;                    // half-size of the search box around the rotation-predicted position
  int min_features = 12;                      // tracked over min_track_frames images or more
  double standstill_max_disparity_px = 1.0;   // median feature displacement over the window: at rest below this
  double min_parallax_px = 8.0;               // median displacement after derotation needed for the dynamic solution
  double max_reprojection_px = 2.0;           // RMS of the solution's reprojection errors
  double gravity = 9.81;                      // m/s², the magnitude |g| imposed
  double max_speed = 20.0;                    // m/s: a larger v₀ is rejected
  double max_split_gravity_deg = 1.5;         // the window's first and last two thirds solved apart: gravity and
  double max_split_velocity_ratio = 0.1;      // velocity must agree within these (velocity: 0.05 m/s + ratio·|v₀|)
  // m/s², the refinement's prior on the accelerometer bias. Tighter than the filter's (imu/accel_bias_std): over a
  // window of under a second the bias is barely separable from gravity's direction and the velocity, and a free bias
  // fits the tracking noise with a wrong sign (0.3 m/s² off on recorded EuRoC windows, a 10 % error of |v0|, a scale
  // error the filter keeps). The filter starts from the window's estimate with its own, broader prior.
  double accel_bias_std = 0.02;
  bool refine_gyro_bias = true;               // the maximum-likelihood refinement also estimates the gyro bias
  void validate() const;
};


struct ViInitFrame {
  TimeNs t = 0;               // in the IMU clock
  vision::ImageView image;    // 8-bit grey, owned by the caller
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
InertialStart inertial_start_from_vi(const ViInitResult& r, const InertialStartOptions& o);

/// Runs the start on the window's images (time-ordered, the first at t_0) and the IMU samples covering them. The
/// gyro bias is estimated with the motion, and taken as the mean gyro at rest.
ViInitResult initialize_visual_inertial(const std::vector<ViInitFrame>& frames, const std::vector<ImuWindowSample>& imu,
                                        const models::PinholeCamera& camera, const math::Pose& T_RS,
                                        const ViInitOptions& options);

}  // namespace rtslam::strategies
