#pragma once
// The estimators of the calibration check (check.hpp), on plain vectors so that they can be tested on synthetic data
// with known answers:
//  - the rotation between two camera views from matched bearings (RANSAC over a 2-point rotation model, then a robust
//    Levenberg-Marquardt on the Sampson epipolar error with the translation direction free);
//  - the gyro integrated over an interval;
//  - the camera–IMU time offset from the cross-correlation of angular-rate magnitudes (rotation-invariant);
//  - the camera–IMU rotation from paired angular rates (hand-eye rotation: Kabsch with a gyro bias, IRLS weights).
//
// Frames: C a camera (x right, y down, z forward), R the robot = IMU frame. A rotation vector θ_C seen by the camera
// over an interval and the gyro's θ_R over the same interval satisfy θ_R = R_RS θ_C (the axis of a rotation is
// carried by the frame change; R_{C0 C1} = R_SR ΔR_{R0 R1} R_RS). Time offset: t_imu = t_cam + t_d (io::Rig).
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "rtslam/core/random.hpp"
#include "rtslam/core/time.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::calib {

/// Rotation R minimizing Σ w_i |a_i − R b_i|² (Kabsch/Umeyama, proper rotation). Needs two non-parallel pairs with
/// positive weight; identity otherwise.
Eigen::Matrix3d kabsch(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b,
                       const std::vector<double>& w = {});

struct RelativeRotationOptions {
  int ransac_iterations = 60;
  double ransac_threshold = 0.012;  // rad: angle between b0 and R b1 for a 2-point-model inlier (parallax included)
  double sampson_threshold = 0.003; // normalized units (≈ px / f): final inliers of the epipolar model
  int min_inliers = 12;
  bool epipolar = true;             // refine with the translation free (false: pure rotation)
};

struct RelativeRotation {
  bool ok = false;
  Eigen::Matrix3d R_01 = Eigen::Matrix3d::Identity();  // view 1 in view 0: b0 ∝ R_01 b1 (+ parallax)
  Eigen::Vector3d t_01 = Eigen::Vector3d::Zero();      // unit translation direction (epipolar model; sign unknown)
  int inliers = 0;
  double rms = 0.0;  // of the inliers' residuals (Sampson, normalized units ≈ px / f)
};

/// The rotation of view 1 in view 0 from unit bearings b0[k] ↔ b1[k] (z > 0 not required). Seeded by `rng`.
RelativeRotation estimate_relative_rotation(const std::vector<Eigen::Vector3d>& b0, const std::vector<Eigen::Vector3d>& b1,
                                            const RelativeRotationOptions& o, Rng& rng);

/// The gyro integrated over [a, b] (IMU clock) with `bias` removed: ΔR_{R(a) R(b)} as a rotation vector (right
/// products of Exp(ω dt), ω linearly interpolated at a and b). nullopt when the samples do not cover [a, b] or a gap
/// inside exceeds max_gap.
std::optional<Eigen::Vector3d> integrate_gyro(const std::vector<io::ImuSample>& imu, TimeNs a, TimeNs b,
                                              const Eigen::Vector3d& bias = Eigen::Vector3d::Zero(),
                                              TimeNs max_gap = 50'000'000);

/// One image interval: the camera's rotation vector over [t0, t1] (camera clock), valid or not.
struct VisualInterval {
  TimeNs t0 = 0, t1 = 0;
  Eigen::Vector3d theta_C = Eigen::Vector3d::Zero();  // Log(R_{C(t0) C(t1)})
  bool valid = false;
  double weight = 1.0;  // a quality weight (e.g. inlier count)
};

struct TimeOffsetResult {
  bool ok = false;
  double t_d_s = 0.0;        // t_imu = t_cam + t_d
  double correlation = 0.0;  // Pearson correlation of the rate magnitudes at the peak
  double second_best = 0.0;  // the best correlation of another peak at least 4 grid steps away
  double std_s = 0.0;        // from the peak's curvature and the correlation (a rough figure)
  int intervals = 0;
};

/// t_d maximizing the correlation of |θ_C| / dt with |θ_R(t0 + t_d, t1 + t_d) − bias dt| / dt over the valid
/// intervals, on a grid of `step_s` over [centre − range, centre + range], refined by a parabola through the peak
/// and its neighbours (sub-grid, hence sub-sample, resolution).
TimeOffsetResult estimate_time_offset(const std::vector<VisualInterval>& visual, const std::vector<io::ImuSample>& imu,
                                      double centre_s, double range_s, double step_s,
                                      const Eigen::Vector3d& bias = Eigen::Vector3d::Zero());

/// t_d minimizing the residual Σ w |θ_R(t_d) − R_RS θ_C − b dt|² near `centre_s` (±range_s, grid + parabola), for a
/// known rotation and bias: sharper than the magnitudes once the rotation is known.
std::optional<double> refine_time_offset(const std::vector<VisualInterval>& visual,
                                         const std::vector<io::ImuSample>& imu, const Eigen::Matrix3d& R_RS,
                                         const Eigen::Vector3d& bias, double centre_s, double range_s, double step_s);

struct HandEyeResult {
  bool ok = false;
  Eigen::Matrix3d R_RS = Eigen::Matrix3d::Identity();
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();  // rad/s
  double rms_rad_s = 0.0;          // weighted RMS of the rate residuals
  double rotation_std_deg = 0.0;   // largest axis std of the rotation from the residuals (a rough figure)
  double excitation_rad_s = 0.0;   // second singular value of the centred camera rates / sqrt(n): 2-axis excitation
  int used = 0;                    // intervals with weight > 0.5
};

/// R_RS and the gyro bias b minimizing Σ ρ(|ω_R,i − R_RS ω_C,i − b|) over paired rates (rad/s), ρ a Huber loss by
/// IRLS (threshold: 2.5 robust sigmas). `ok` is false when the camera rates do not excite two axes
/// (excitation_rad_s < min_excitation_rad_s) or fewer than 8 pairs are given.
HandEyeResult estimate_hand_eye_rotation(const std::vector<Eigen::Vector3d>& w_C, const std::vector<Eigen::Vector3d>& w_R,
                                         const std::vector<double>& weights, double min_excitation_rad_s);

/// The upper median of `values` (the element at size / 2 once sorted); 0 for none.
double median_of(std::vector<double> values);

}  // namespace rtslam::calib
