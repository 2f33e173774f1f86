#include "rtslam/slam/observation.hpp"

#include "rtslam/slam/landmark.hpp"
#include "rtslam/slam/robot.hpp"
#include "rtslam/slam/sensor.hpp"

namespace rtslam::slam {

bool predict_observation(const filter::State& state, const Eigen::VectorXd& mean, Observation& obs, double margin,
                         bool with_jacobians, const Eigen::VectorXd* lin_mean) {
  const Sensor& sensor = *obs.sensor;
  const Landmark& lmk = *obs.landmark;
  const Robot& robot = sensor.robot();
  const bool estimated_extrinsics = sensor.block() != filter::kNoBlock;
  const bool estimated_time = sensor.time_block() != filter::kNoBlock;
  Eigen::Matrix<double, 6, 6> J_TWS_TWR, J_TWS_TRS;
  Eigen::Matrix<double, 6, 1> J_TWS_td = Eigen::Matrix<double, 6, 1>::Zero();
  const math::Pose T_WS = sensor.pose_in_world(mean, with_jacobians ? &J_TWS_TWR : nullptr,
                                               with_jacobians && estimated_extrinsics ? &J_TWS_TRS : nullptr,
                                               with_jacobians && estimated_time ? &J_TWS_td : nullptr);
  Eigen::Matrix<double, 3, 6> J_h_TWS;
  LandmarkJacobian J_h_L;
  const Eigen::Vector3d h_S =
      lmk.to_sensor(mean, T_WS, with_jacobians ? &J_h_TWS : nullptr, with_jacobians ? &J_h_L : nullptr);
  Eigen::Matrix<double, 2, 3> J_z_h;
  obs.projectable = sensor.project(h_S, obs.h, with_jacobians ? &J_z_h : nullptr);
  obs.visible = obs.projectable && sensor.in_field(obs.h, margin);
  if (with_jacobians && obs.projectable && lin_mean != nullptr) {
    // First-estimate Jacobians: the chain at the linearization mean (h stays the prediction at `mean`).
    const math::Pose T_WS_lin = sensor.pose_in_world(*lin_mean, &J_TWS_TWR, estimated_extrinsics ? &J_TWS_TRS : nullptr,
                                                     estimated_time ? &J_TWS_td : nullptr);
    const Eigen::Vector3d h_S_lin = lmk.to_sensor(*lin_mean, T_WS_lin, &J_h_TWS, &J_h_L);
    Eigen::Vector2d z_lin;
    Eigen::Matrix<double, 2, 3> J_z_h_lin;
    if (sensor.project(h_S_lin, z_lin, &J_z_h_lin)) {
      J_z_h = J_z_h_lin;
    } else {  // not projectable at the first estimate: linearize at the current mean
      sensor.pose_in_world(mean, &J_TWS_TWR, estimated_extrinsics ? &J_TWS_TRS : nullptr,
                           estimated_time ? &J_TWS_td : nullptr);
      lmk.to_sensor(mean, T_WS, &J_h_TWS, &J_h_L);
    }
  }
  obs.block_count = 0;
  obs.blocks[static_cast<std::size_t>(obs.block_count++)] = robot.block();
  if (estimated_extrinsics) obs.blocks[static_cast<std::size_t>(obs.block_count++)] = sensor.block();
  if (estimated_time) obs.blocks[static_cast<std::size_t>(obs.block_count++)] = sensor.time_block();
  obs.blocks[static_cast<std::size_t>(obs.block_count++)] = lmk.block();
  if (with_jacobians && obs.projectable) {
    const int tr = state.block(robot.block()).tangent_size();
    const int ts = estimated_extrinsics ? 6 : 0;
    const int tt = estimated_time ? 1 : 0;
    const int tl = state.block(lmk.block()).tangent_size();
    obs.H.setZero(2, tr + ts + tt + tl);
    // h depends on the state through the sensor pose T_WS and the landmark:
    // H = [A_WS J_TWS_TWR, A_WS J_TWS_TRS, A_WS J_TWS_td, A_L] with A = [J_z_TWS, J_z_L].
    Eigen::Matrix<double, 2, Eigen::Dynamic, Eigen::ColMajor, 2, 6 + kMaxLandmarkTangent> A(2, 6 + tl);
    A.leftCols<6>().noalias() = J_z_h * J_h_TWS;
    A.rightCols(tl).noalias() = J_z_h * J_h_L.leftCols(tl);
    if (state.nullspace_dim() > 0) {
      // Observability constraints: A [N_WS; N_L] = 0, with N_WS = J_TWS_TWR N_R (+ J_TWS_TRS N_S) the sensor pose's
      // rows of the tracked basis. Constraining A, not H, keeps H's structure: no velocity, bias or gravity
      // columns appear, and directions that leave T_WS unchanged (robot and extrinsics moving together) stay
      // unobservable. A time offset does not move with the world (zero rows): its column A_WS J_TWS_td is the
      // constrained A's.
      const int k = state.nullspace_dim();
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 6 + kMaxLandmarkTangent, 16> N(6 + tl, k);
      N.topRows<6>().noalias() = J_TWS_TWR * state.nullspace(robot.block()).topRows<6>();
      if (estimated_extrinsics) N.topRows<6>().noalias() += J_TWS_TRS * state.nullspace(sensor.block());
      N.bottomRows(tl) = state.nullspace(lmk.block());
      filter::project_out_basis(A, N);
    }
    obs.H.leftCols<6>().noalias() = A.leftCols<6>() * J_TWS_TWR;
    if (estimated_extrinsics) obs.H.middleCols<6>(tr).noalias() = A.leftCols<6>() * J_TWS_TRS;
    if (estimated_time) obs.H.col(tr + ts).noalias() = A.leftCols<6>() * J_TWS_td;
    obs.H.rightCols(tl) = A.rightCols(tl);
    obs.R_depth.setZero();
    Eigen::Vector3d dh_drho;
    double var_rho = 0.0;
    if (lmk.inverse_depth_direction(state, mean, T_WS, dh_drho, var_rho) && h_S.z() != 0.0) {
      const Eigen::Vector2d dz = J_z_h * dh_drho;
      const Eigen::Vector2d d2z = -2.0 * (dh_drho.z() / h_S.z()) * dz;
      obs.R_depth.noalias() = 0.5 * var_rho * var_rho * d2z * d2z.transpose();
    }
    obs.lin_T_WS << T_WS.p, math::quat_to_wxyz(T_WS.q);
    obs.lin_landmark = mean.segment(state.block(lmk.block()).ambient_offset, state.block(lmk.block()).ambient_size());
  }
  obs.depth = h_S.norm() > 0.0 ? h_S.z() : 0.0;
  return obs.visible;
}

Eigen::Matrix2d measurement_noise(const Observation& obs, double sigma, bool second_order) {
  Eigen::Matrix2d R = sigma * sigma * Eigen::Matrix2d::Identity();
  if (second_order) R += obs.R_depth;
  return R;
}

void compute_innovation_covariance(const filter::State& state, Observation& obs, double sigma, bool second_order) {
  obs.R = measurement_noise(obs, sigma, second_order);
  state.innovation_covariance(obs.involved(), obs.H, obs.R, obs.S);
}

}  // namespace rtslam::slam
