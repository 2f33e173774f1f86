#pragma once
// Trajectory alignment: the transform S that maps the estimate onto the ground truth (est' = S ∘ est), fitted on
// associated positions. Umeyama (1991) least squares for SE(3)/Sim(3), the same equations as evo's
// geometry.umeyama_alignment; position + yaw (4-DoF, gravity along z in both frames: the usual choice for VIO);
// first-pose (evo's --align_origin: S = T_gt0 · T_est0⁻¹); none.
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/trajectory.hpp"
#include "rtslam/eval/geometry.hpp"

namespace rtslam::eval {

enum class Alignment { Se3, Sim3, PosYaw, Origin, None };

/// "se3" | "sim3" | "posyaw" | "origin" | "none"; throws ConfigError naming the value otherwise.
Alignment parse_alignment(std::string_view name);
std::string to_string(Alignment a);

/// Least-squares S (rotation, translation, and scale if `with_scale`) minimizing Σ |dst_i − S(src_i)|².
/// Throws DataError when sizes differ, fewer than 3 points are given, or the point cloud is degenerate (rank < 2).
Sim3 umeyama(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst, bool with_scale);

/// Least-squares rotation about z plus translation minimizing Σ |dst_i − (R_z(ψ) src_i + t)|² (closed form).
/// Throws DataError when sizes differ, the set is empty, or the horizontal spread is zero.
Sim3 align_position_yaw(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst);

/// Smallest ratio of the second to the first principal standard deviation of a trajectory's positions for an SE3 /
/// Sim3 alignment: below it they lie on a line, and the rotation about it is undetermined.
constexpr double kMinAlignmentSpreadRatio = 1e-3;

/// Refuses (DataError naming the method and the numbers) an SE3 / Sim3 alignment that would be meaningless: fewer
/// poses than give as many residual degrees of freedom as the fit has parameters (4 for SE3, 5 for Sim3), or
/// positions of either trajectory on a line (kMinAlignmentSpreadRatio). Other methods pass.
void check_alignment_geometry(const std::vector<Eigen::Vector3d>& est, const std::vector<Eigen::Vector3d>& gt,
                              Alignment method);

/// The alignment of `est` onto `gt`; both must be associated (same length, pose i ↔ pose i). SE3 and Sim3 pass
/// check_alignment_geometry first.
Sim3 compute_alignment(const Trajectory& est, const Trajectory& gt, Alignment method);

/// est' = S ∘ est for every pose: p' = s R p + t, q' = q(R) ⊗ q. A pose covariance [δp δθ] is carried along:
/// δp' = s R δp (world-frame position error), δθ unchanged (right perturbation in the robot frame).
Trajectory apply_alignment(const Sim3& S, const Trajectory& est);

/// How well the positions determine an SE3 / Sim3 least-squares alignment, to first order with isotropic residuals:
/// with the fit's residual variance per coordinate σ² = Σ|gt − S(est)|² / (3n − p) (p = 6 or 7 parameters), the
/// standard deviation of the fitted rotation about its worst-determined axis is σ / sqrt(λ_min(J)), J = Σ (|r|² I −
/// r rᵀ) the inertia of the centred aligned positions r, and the relative standard deviation of a Sim3 scale is
/// σ / sqrt(Σ|r|²). Little motion against the residual (a standstill, a few millimetres of jitter) leaves both
/// large: the fitted rotation and scale are then the residual's, and so are the ATE's rotation part and the scale
/// error. `aligned`: the estimate after the alignment, associated with `gt`.
struct AlignmentSpread {
  double rotation_std_deg = 0.0;
  double scale_rel_std = 0.0;  // std(s) / s
};
AlignmentSpread alignment_spread(const Trajectory& aligned, const Trajectory& gt, Alignment method);

/// Above these the alignment says more about the residual than about the run (eval's warning): a degree of rotation
/// and a percent of scale, the resolution at which ATE rotations and scale errors are compared.
constexpr double kMaxAlignmentRotationStdDeg = 1.0;
constexpr double kMaxAlignmentScaleStd = 0.01;

}  // namespace rtslam::eval
