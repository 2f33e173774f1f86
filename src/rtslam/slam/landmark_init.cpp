#include "rtslam/slam/landmark_init.hpp"

#include <limits>

#include "rtslam/models/landmarks/euclidean_point.hpp"

namespace rtslam::slam {

Landmark* init_ahp_landmark(Map& map, Sensor& sensor, const Eigen::Vector2d& z, double sigma_px,
                            const models::AhpPrior& prior, long frame) {
  filter::State& state = map.state();
  const Robot& robot = sensor.robot();
  Eigen::Vector3d ray_S;
  Eigen::Matrix<double, 3, 2> J_ray_z;
  if (!sensor.back_project(z, ray_S, &J_ray_z)) return nullptr;
  const bool estimated_extrinsics = sensor.block() != filter::kNoBlock;
  const bool estimated_time = sensor.time_block() != filter::kNoBlock;
  Eigen::Matrix<double, 6, 6> J_TWS_TWR, J_TWS_TRS;
  Eigen::Matrix<double, 6, 1> J_TWS_td;
  const math::Pose T_WS = sensor.pose_in_world(state.mean_vector(), &J_TWS_TWR, &J_TWS_TRS, &J_TWS_td);
  Eigen::Matrix<double, 7, 3> J_L_pWS;
  Eigen::Matrix<double, 7, 3> J_L_qWS;
  Eigen::Matrix<double, 7, 3> J_L_ray;
  Eigen::Matrix<double, 7, 1> J_L_rho;
  const models::Vector7d L =
      models::ahp_from_ray(T_WS, ray_S, prior.rho_mean(), &J_L_pWS, &J_L_qWS, &J_L_ray, &J_L_rho);
  const int tr = state.block(robot.block()).tangent_size();
  const int ts = estimated_extrinsics ? 6 : 0;
  const int tt = estimated_time ? 1 : 0;
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(7, tr + ts + tt);
  Eigen::Matrix<double, 7, 6> J_L_TWS;
  J_L_TWS << J_L_pWS, J_L_qWS;
  J.leftCols<6>() = J_L_TWS * J_TWS_TWR;
  if (estimated_extrinsics) J.middleCols<6>(tr) = J_L_TWS * J_TWS_TRS;
  if (estimated_time) J.col(tr + ts) = J_L_TWS * J_TWS_td;  // the anchor is the camera at the estimated capture time
  const Eigen::Matrix<double, 7, 2> J_L_z = J_L_ray * J_ray_z;
  Eigen::Matrix<double, 7, 7> Q = sigma_px * sigma_px * J_L_z * J_L_z.transpose();
  Q.noalias() += prior.rho_sigma() * prior.rho_sigma() * J_L_rho * J_L_rho.transpose();
  filter::BlockId parents[3] = {robot.block(), filter::kNoBlock, filter::kNoBlock};
  std::size_t n_parents = 1;
  if (estimated_extrinsics) parents[n_parents++] = sensor.block();
  if (estimated_time) parents[n_parents++] = sensor.time_block();
  Landmark* lmk = map.add_landmark(filter::BlockLayout::euclidean(7), L,
                                   std::span<const filter::BlockId>(parents, n_parents), J, Q,
                                   [](int id, filter::BlockId b) { return std::make_unique<AhpPointLandmark>(id, b); });
  if (lmk) {
    lmk->frame_created = frame;
    lmk->sensor_created = sensor.id();
  }
  return lmk;
}

Landmark* reparametrize_to_euclidean(Map& map, Landmark& ahp) {
  if (ahp.type() != LandmarkType::AhpPoint) return &ahp;
  const models::Vector7d L = map.state().mean(ahp.block());
  Eigen::Matrix<double, 3, 7> J_p_L;
  const Eigen::Vector3d p = models::ahp_to_euclidean(L, &J_p_L);
  return map.reparametrize(ahp, filter::BlockLayout::euclidean(3), p, J_p_L, [](int id, filter::BlockId b) {
    return std::make_unique<EuclideanPointLandmark>(id, b);
  });
}

double linearity_index(const Map& map, const Landmark& lmk, const Eigen::Vector3d& p_WS) {
  if (lmk.type() != LandmarkType::AhpPoint) return std::numeric_limits<double>::infinity();
  const models::Vector7d L = map.state().mean(lmk.block());
  const Eigen::Matrix<double, 7, 7> P = map.state().cov(lmk.block());
  return models::ahp_linearity_index(L, P, p_WS);
}

}  // namespace rtslam::slam
