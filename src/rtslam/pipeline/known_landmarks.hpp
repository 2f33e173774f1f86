#pragma once
// Known-landmark initialization (as MonoSLAM does it): a file set of 3D points with their image patches and the
// initial camera state fixes the scale and the world frame from the first frame.
//
// File set (MonoSLAM/SceneLib, ../shared/datasets/monoslam-davison/init/): `initial_state.json` with the camera
// state `xv = [r(3) q(4, w x y z) v(3) ω(3)]`, its 13×13 covariance `pxx` in those ambient coordinates, and
// `features[i].yi` (3D points in W); the patches `known_patchN.pgm` (odd squares) as seen from that state.
// Convention `robot` (default): the file's camera state is the robot state as is. That is the case for MonoSLAM data
// read by io::load_monoslam_camera, whose T_RS = diag(−1, −1, 1) makes the robot frame SceneLib's camera frame (x
// LEFT, y UP, z forward). Convention `scenelib`: the rig's camera is the robot (T_RS = identity, checked by the
// caller) in our optical frame (x right, y down), so the state is converted: R_WR = R(q) · diag(−1, −1, 1),
// ω_R = diag(−1, −1, 1) ω.
// Known points become Euclidean landmarks with a tiny covariance (they define W) and a PointDescriptor whose view
// is the initial camera pose.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rtslam/slam/map.hpp"
#include "rtslam/vision/image.hpp"

namespace rtslam::pipeline {

struct KnownLandmarkSet {
  Eigen::VectorXd robot_mean;  // 13: [p q(wxyz) v ω] of the constant-velocity robot (our frames)
  Eigen::MatrixXd robot_cov;   // 12×12 tangent covariance [δp δθ v ω]
  std::vector<Eigen::Vector3d> points_W;
  std::vector<vision::Image> patches;
};

/// |q| may differ from 1 by this much in an initial state (then it is normalized); more is not a rotation.
constexpr double kUnitQuaternionTolerance = 1e-3;

/// Plausibility of an initial state read from `where`: x finite, its quaternion x[q_index..q_index+3] of norm 1 within
/// kUnitQuaternionTolerance, P square, finite, symmetric and positive semi-definite (zero variances are the gauge).
/// Throws ConfigError naming `where`, the quantity, its value and the bound.
void check_initial_state(const Eigen::VectorXd& x, const Eigen::MatrixXd& P, int q_index, const std::string& where);

/// Loads a MonoSLAM-style known-landmark folder; the initial state is checked by check_initial_state; `convention` is "robot" or "scenelib". Throws IoError /
/// ConfigError naming the file and the problem.
KnownLandmarkSet load_known_landmarks(const std::string& folder, const std::string& convention);

/// Adds the known points as Euclidean landmarks seen by `sensor` from the robot's current pose (which must be the
/// set's initial state). Returns how many were added (points behind the camera or outside the image are skipped).
int add_known_landmarks(slam::Map& map, slam::Sensor& sensor, const KnownLandmarkSet& set);

}  // namespace rtslam::pipeline
