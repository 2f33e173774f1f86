#include "estimate.hpp"

#include "rtslam/math/rotation.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#include "rtslam/slam/landmark.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/robot.hpp"

namespace rtslam::ros_node {

Eigen::Matrix<double, 6, 6> pose_covariance_to_ros(const Eigen::Matrix<double, 6, 6>& cov,
                                                   const Eigen::Quaterniond& q_WR) {
  Eigen::Matrix<double, 6, 6> J = Eigen::Matrix<double, 6, 6>::Identity();
  J.bottomRightCorner<3, 3>() = q_WR.toRotationMatrix();
  Eigen::Matrix<double, 6, 6> out = J * cov * J.transpose();
  return 0.5 * (out + out.transpose());
}

Estimate make_estimate(const pipeline::ImageSlamFrame& frame, const Eigen::Isometry3d& T_RS, bool with_map) {
  const slam::Map& map = *frame.map;
  const slam::Robot& robot = *map.robots().front();
  const filter::State& state = map.state();
  const auto x = state.mean(robot.block());
  const auto P = state.cov(robot.block());
  Estimate e;
  e.t = frame.t;
  const math::Pose T_WR = robot.pose();
  e.p_WR = T_WR.p;
  e.q_WR = T_WR.q;
  e.cov_pose = pose_covariance_to_ros(P.topLeftCorner<6, 6>(), T_WR.q);
  // Both robot models start [p q v ...] (tangent [δp δθ δv ...]), v in W.
  const Eigen::Matrix3d R_WR = T_WR.q.toRotationMatrix();
  const Eigen::Vector3d v_W = x.segment<3>(7);
  e.v_R = R_WR.transpose() * v_W;
  Eigen::Matrix<double, 3, 9> J_vR_x = Eigen::Matrix<double, 3, 9>::Zero();  // over [δp δθ δv]
  J_vR_x.block<3, 3>(0, 3) = math::skew(e.v_R);
  J_vR_x.block<3, 3>(0, 6) = R_WR.transpose();
  e.cov_v_R = J_vR_x * P.topLeftCorner<9, 9>() * J_vR_x.transpose();
  if (dynamic_cast<const slam::ConstantVelocityRobot*>(&robot) != nullptr) {
    e.w_R = x.segment<3>(10);  // [p q v ω], ω in R
    e.cov_w_R = P.block<3, 3>(9, 9);
  }
  e.T_RS = T_RS;
  e.with_map = with_map;
  if (with_map) {
    const Eigen::VectorXd& mean = state.mean_vector();
    e.landmarks.reserve(map.landmarks().size());
    e.landmark_ids.reserve(map.landmarks().size());
    for (const auto& l : map.landmarks()) {
      e.landmarks.push_back(l->position(mean).cast<float>());
      e.landmark_ids.push_back(static_cast<std::uint32_t>(l->id()));
    }
  }
  return e;
}

}  // namespace rtslam::ros_node
