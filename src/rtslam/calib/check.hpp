#pragma once
// The calibration check (issue 17, item 6): the camera–IMU rotation and time offset measured from the data, against
// the configured T_RS rotation and t_d.
//
// From a Source and its Rig, over the first `duration` seconds of motion (motion onset: the gyro's 0.1 s mean leaves
// the mean of the first 0.5 s by more than `onset_rate`; the window starts 0.5 s earlier):
//  1. Harris corners on a grid of cells, tracked image to image by ZNCC around a constant-image-velocity prediction
//     (no gyro: the gyro's calibration is what is checked), undistorted to bearings with the calibrated intrinsics;
//  2. each image interval's camera rotation: RANSAC over a 2-point rotation model, then robust Levenberg-Marquardt on
//     the Sampson epipolar error (translation direction free), estimators.hpp;
//  3. the time offset t_d (t_imu = t_cam + t_d): cross-correlation of the angular-rate magnitudes of camera and gyro
//     over [configured − offset_range, configured + offset_range] (1 ms grid, parabola at the peak);
//  4. the rotation R_RS and the gyro bias: hand-eye on the interval rates (Kabsch, Huber IRLS) at that offset; then
//     the offset refined on the full rate vectors and the rotation solved again.
// Verdict: `warning` when the measured rotation is more than max_rotation_deg from the configured one (with "looks
// like the inverse of T_RS" when it is within max_rotation_deg of R_RSᵀ) or the offset more than max_offset_ms from
// the configured t_d; `not_enough_motion` when a quantity could not be measured (too little rotation about two axes,
// or rates that do not correlate); `failed` when the data do not allow the check (no IMU, too few images tracked).
// The library logs nothing above debug; the caller prints `lines()` and warns with `warnings`.
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>
#include <yaml-cpp/yaml.h>

#include "rtslam/calib/stream.hpp"
#include "rtslam/core/time.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/io/calibration.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/source.hpp"

namespace rtslam::calib {

struct CheckOptions {
  bool enabled = true;              // `rtslam run` (inertial configurations) runs the check before the run
  double duration_s = 6.0;          // s of motion analysed, in (0.5, 120]
  double max_wait_s = 30.0;         // s from the start to wait for motion, in [0, 3600]
  double onset_rate = 0.15;         // rad/s: gyro change marking the motion onset, in [0, 10]
  double max_rotation_deg = 3.0;    // warn above this rotation error, in (0, 180]
  double max_offset_ms = 5.0;       // warn above this offset error, in (0, 1000]
  double offset_range_ms = 100.0;   // searched around the configured t_d, in [10, 1000]
  double min_excitation = 0.04;     // rad/s: camera-rate spread needed about two axes, in [0, 10]; the rotation is
                                    // also refused when its std exceeds max_rotation_deg / 3
  double min_correlation = 0.6;     // rate-magnitude correlation needed for an offset, in [0, 1]
  int cells_x = 10, cells_y = 8;    // feature grid, in [2, 64]
  int patch_size = 15;              // ZNCC template (odd), in [5, 31]
  double min_score = 0.85;          // ZNCC acceptance, in [0, 1]
  double search_px = 30.0;          // half-size of the search box around the predicted position, in [2, 200]
  double gap_factor = 1.5;          // a stream interval > gap_factor × median is a gap, in (1, 100]
  bool epipolar = true;             // inter-image rotation with the translation free (false: pure rotation)
  /// Threads for the image intervals' rotations (not a YAML key): 0 = one per core, at most 4. The results do not
  /// depend on it (each interval has its own generator).
  int threads = 0;

  /// Throws ConfigError naming the key, the value and the bound.
  void validate() const;
  /// Keys: enabled, duration, max_wait, onset_rate, max_rotation_deg, max_offset_ms, offset_range_ms,
  /// min_excitation, min_correlation, cells_x, cells_y, patch_size, min_score, search_px, gap_factor, epipolar.
  /// Unknown keys are errors (map.finish()); validates.
  static CheckOptions from_yaml(YamlMap& map);
  YAML::Node to_yaml() const;
};

enum class Verdict { ok, warning, not_enough_motion, failed };
std::string to_string(Verdict v);

struct CheckResult {
  Verdict verdict = Verdict::failed;
  std::string reason;                 // why failed / not measured (empty when everything was measured)
  std::vector<std::string> warnings;  // one sentence each, naming the measured and configured values
  // The window analysed (s after the stream's first measurement) and what it gave.
  double window_start_s = 0.0, window_end_s = 0.0;
  int images = 0;          // images in the window
  int intervals = 0;       // image intervals
  int intervals_valid = 0; // with a camera rotation
  double median_features = 0.0;  // tracked pairs per interval (median)
  double visual_rms_px = 0.0;    // median over the intervals of the epipolar RMS, in px
  // Rotation.
  bool rotation_measured = false;
  Eigen::Matrix3d R_RS_measured = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R_RS_configured = Eigen::Matrix3d::Identity();
  double rotation_error_deg = 0.0;       // angle between measured and configured
  double rotation_to_inverse_deg = 0.0;  // angle between measured and the configured one's inverse
  bool looks_inverted = false;
  double rotation_std_deg = 0.0;
  double excitation_rad_s = 0.0;
  double rate_rms_rad_s = 0.0;           // residual of the hand-eye fit
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero();  // rad/s, a by-product
  // Time offset (t_imu = t_cam + t_d).
  bool offset_measured = false;
  double t_d_measured_ms = 0.0;
  double t_d_configured_ms = 0.0;
  double offset_error_ms = 0.0;
  double correlation = 0.0;              // of the rate magnitudes at the peak
  double second_peak_correlation = 0.0;
  StreamReport stream;                   // of the window read
  double cost_ms = 0.0;                  // wall time of the check

  /// Printable lines (no trailing newline), e.g. "calibration check: warning — ...".
  std::vector<std::string> lines() const;
  nlohmann::json to_json() const;
};

/// Checks the calibration of camera `camera` of `rig` against the data of `source` (read from its current position;
/// images of other cameras are skipped). `t_d_configured` is the offset the run uses (the rig's or the config's).
/// Never throws for bad data (the verdict says failed); rethrows the source's own errors.
CheckResult check_calibration(io::Source& source, const io::Rig& rig, int camera, TimeNs t_d_configured,
                              const CheckOptions& options);

/// Opens `spec` (io::open_dataset with `dataset_options`, cameras = {camera}, IMU on, from its start_offset_s to the
/// end) and checks it; t_d_configured defaults to the rig's. Images are decoded ahead in `prefetch_threads` threads
/// as io::start_prefetch takes them (< 0: the default, 0: off; the run's --prefetch). cost_ms includes the opening.
CheckResult check_dataset_calibration(const std::string& spec, io::DatasetOptions dataset_options, int camera,
                                      std::optional<TimeNs> t_d_configured, const CheckOptions& options,
                                      int prefetch_threads = -1);

}  // namespace rtslam::calib
