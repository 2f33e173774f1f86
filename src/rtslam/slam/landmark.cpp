#include "rtslam/slam/landmark.hpp"

#include "rtslam/models/landmarks/ahp.hpp"
#include "rtslam/models/landmarks/euclidean_point.hpp"
#include "rtslam/slam/sensor.hpp"

namespace rtslam::slam {

const char* to_string(LandmarkType t) {
  switch (t) {
    case LandmarkType::AhpPoint: return "ahp";
    case LandmarkType::EuclideanPoint: return "euclidean";
  }
  return "?";
}

Landmark::~Landmark() = default;

void Landmark::scale_lengths(double, const Eigen::Vector3d&, Eigen::Ref<Eigen::VectorXd>, Eigen::Ref<Eigen::VectorXd>) {
  RTSLAM_CHECK(false, "Landmark::scale_lengths: this parametrization cannot change its unit of length");
}

void AhpPointLandmark::scale_lengths(double c, const Eigen::Vector3d& centre, Eigen::Ref<Eigen::VectorXd> mean,
                                     Eigen::Ref<Eigen::VectorXd> d) {
  d << c, c, c, 1.0, 1.0, 1.0, 1.0 / c;
  mean.head<3>() = centre + c * (mean.head<3>() - centre);
  mean[6] /= c;
  if (first_estimate.size() == 7) {
    first_estimate.head<3>() = centre + c * (first_estimate.head<3>() - centre);
    first_estimate[6] /= c;
  }
}

void EuclideanPointLandmark::scale_lengths(double c, const Eigen::Vector3d& centre, Eigen::Ref<Eigen::VectorXd> mean,
                                           Eigen::Ref<Eigen::VectorXd> d) {
  d.setConstant(c);
  mean = centre + c * (mean - centre);
  if (first_estimate.size() == 3) first_estimate = centre + c * (first_estimate - centre);
}

Observation* Landmark::observation_of(const Sensor& s) {
  for (auto& o : observations_)
    if (o.sensor == &s) return &o;
  return nullptr;
}

Eigen::Vector3d AhpPointLandmark::to_sensor(const Eigen::VectorXd& mean, const math::Pose& T_WS,
                                            Eigen::Matrix<double, 3, 6>* J_h_TWS, LandmarkJacobian* J_h_L) const {
  // The map is owned elsewhere; the landmark reads its block through the mean vector and the offset cached by Map.
  const models::Vector7d L = mean.segment<7>(ambient_offset_);
  Eigen::Matrix3d J_p;
  Eigen::Matrix3d J_q;
  Eigen::Matrix<double, 3, 7> J_L;
  const Eigen::Vector3d h = models::ahp_to_sensor(L, T_WS, J_h_TWS ? &J_p : nullptr, J_h_TWS ? &J_q : nullptr,
                                                  J_h_L ? &J_L : nullptr);
  if (J_h_TWS) *J_h_TWS << J_p, J_q;
  if (J_h_L) *J_h_L = J_L;
  return h;
}

Eigen::Vector3d AhpPointLandmark::position(const Eigen::VectorXd& mean) const {
  return models::ahp_to_euclidean(mean.segment<7>(ambient_offset_));
}

bool AhpPointLandmark::inverse_depth_direction(const filter::State& state, const Eigen::VectorXd& mean,
                                               const math::Pose& T_WS, Eigen::Vector3d& dh_drho,
                                               double& var_rho) const {
  dh_drho = -(T_WS.q.conjugate() * (T_WS.p - mean.segment<3>(ambient_offset_)));
  var_rho = state.cov(block())(6, 6);
  return true;
}

Eigen::Vector3d EuclideanPointLandmark::to_sensor(const Eigen::VectorXd& mean, const math::Pose& T_WS,
                                                  Eigen::Matrix<double, 3, 6>* J_h_TWS, LandmarkJacobian* J_h_L) const {
  Eigen::Matrix3d J_p;
  Eigen::Matrix3d J_q;
  Eigen::Matrix3d J_L;
  const Eigen::Vector3d h = models::point_to_sensor(mean.segment<3>(ambient_offset_), T_WS, J_h_TWS ? &J_p : nullptr,
                                                    J_h_TWS ? &J_q : nullptr, J_h_L ? &J_L : nullptr);
  if (J_h_TWS) *J_h_TWS << J_p, J_q;
  if (J_h_L) *J_h_L = J_L;
  return h;
}

Eigen::Vector3d EuclideanPointLandmark::position(const Eigen::VectorXd& mean) const {
  return mean.segment<3>(ambient_offset_);
}

}  // namespace rtslam::slam
