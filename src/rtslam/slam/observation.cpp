#include "rtslam/slam/observation.hpp"

#include "rtslam/slam/landmark.hpp"
#include "rtslam/slam/robot.hpp"
#include "rtslam/slam/sensor.hpp"

namespace rtslam::slam {

bool predict_observation(const filter::State& state, const Eigen::VectorXd& mean, Observation& obs, double margin,
                         bool with_jacobians) {
  const Sensor& sensor = *obs.sensor;
  const Landmark& lmk = *obs.landmark;
  const Robot& robot = sensor.robot();
  Eigen::Matrix<double, 6, 6> J_TWS_TWR;
  const math::Pose T_WS = sensor.pose_in_world(mean, with_jacobians ? &J_TWS_TWR : nullptr);
  Eigen::Matrix<double, 3, 6> J_h_TWS;
  LandmarkJacobian J_h_L;
  const Eigen::Vector3d h_S =
      lmk.to_sensor(mean, T_WS, with_jacobians ? &J_h_TWS : nullptr, with_jacobians ? &J_h_L : nullptr);
  Eigen::Matrix<double, 2, 3> J_z_h;
  obs.projectable = sensor.project(h_S, obs.h, with_jacobians ? &J_z_h : nullptr);
  obs.visible = obs.projectable && sensor.in_field(obs.h, margin);
  obs.blocks = {robot.block(), lmk.block()};
  if (with_jacobians && obs.projectable) {
    const int tr = state.block(robot.block()).tangent_size();
    const int tl = state.block(lmk.block()).tangent_size();
    obs.H.setZero(2, tr + tl);
    obs.H.leftCols<6>().noalias() = J_z_h * J_h_TWS * J_TWS_TWR;
    obs.H.rightCols(tl).noalias() = J_z_h * J_h_L;
    // Observability constraints (when the filter tracks its unobservable basis): H N = 0.
    state.constrain_jacobian(obs.blocks, obs.H);
    obs.lin_T_WS << T_WS.p, math::quat_to_wxyz(T_WS.q);
    obs.lin_landmark = mean.segment(state.block(lmk.block()).ambient_offset, state.block(lmk.block()).ambient_size());
  }
  obs.depth = h_S.norm() > 0.0 ? h_S.z() : 0.0;
  return obs.visible;
}

void compute_innovation_covariance(const filter::State& state, Observation& obs, double sigma) {
  obs.R = sigma * sigma * Eigen::Matrix2d::Identity();
  state.innovation_covariance(obs.blocks, obs.H, obs.R, obs.S);
}

}  // namespace rtslam::slam
