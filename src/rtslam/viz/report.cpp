#include "rtslam/viz/report.hpp"

#include <Eigen/Cholesky>

#include "rtslam/slam/sensor.hpp"

namespace rtslam::viz {

FrameReport make_report(int index, TimeNs t, const slam::Map& map, const std::vector<FrameMatch>& matches,
                        const cv::Mat& grey, const slam::FrameStats* stats, const strategies::InitGrid* grid) {
  FrameReport r;
  r.index = index;
  r.t = t;
  // Share the pixels when the Mat owns them (reference counted: the report keeps them alive), else copy.
  if (!grey.empty()) r.image = grey.u != nullptr ? grey : grey.clone();
  const filter::State& state = map.state();
  const Eigen::VectorXd& mean = state.mean_vector();
  if (!map.robots().empty()) {
    const slam::Robot& robot = *map.robots().front();
    r.T_WR = robot.pose();
    r.cov_pose = state.cov(robot.block()).topLeftCorner<6, 6>();
    r.T_WS = r.T_WR;
    if (!robot.sensors().empty()) {
      const slam::Sensor& sensor = *robot.sensors().front();
      r.T_WS = sensor.pose_in_world(mean);
      if (const auto* cam = dynamic_cast<const slam::PinholeSensor*>(&sensor)) {
        const auto& in = cam->camera().intrinsics();
        r.camera = CameraInfo{in.width, in.height, in.fx, in.fy, in.cx, in.cy};
      }
    }
  }
  r.landmarks.reserve(map.landmarks().size());
  for (const auto& l : map.landmarks()) {
    LandmarkReport lr;
    lr.id = l->id();
    lr.euclidean = l->type() == slam::LandmarkType::EuclideanPoint;
    lr.p_W = l->position(mean);
    const auto P = state.cov(l->block());
    if (lr.euclidean) {
      lr.cov_W = P;
    } else {
      // p = p0 + m / ρ: J_p_L = [I  I/ρ  −m/ρ²] over [p0 m ρ].
      const auto L = state.mean(l->block());
      const double rho = L[6];
      Eigen::Matrix<double, 3, 7> J;
      J << Eigen::Matrix3d::Identity(), Eigen::Matrix3d::Identity() / rho, -L.segment<3>(3) / (rho * rho);
      lr.cov_W = J * P * J.transpose();
    }
    // Made by this datum: its map frame and its sensor (a stereo pair shares the frame; without the stats, one
    // camera's frames are its data).
    lr.created_now = stats != nullptr ? l->frame_created == stats->frame && l->sensor_created == stats->sensor_id
                                      : l->frame_created == index;
    if (lr.created_now) {
      if (const strategies::PointDescriptor* d = strategies::point_descriptor(*l)) lr.z0_px = d->z0_px;
    }
    r.landmarks.push_back(std::move(lr));
  }
  r.matches = matches;
  if (grid != nullptr) {
    r.grid.reserve(static_cast<std::size_t>(grid->cell_count()));
    for (int c = 0; c < grid->cell_count(); ++c) r.grid.push_back(GridCell{grid->cell_rect(c), grid->occupied(c)});
  }
  if (stats != nullptr) {
    r.stats = *stats;
    r.has_timing = true;
  } else {
    r.stats.t = t;
    r.stats.landmarks_in_map = static_cast<int>(map.landmarks().size());
    r.stats.visible = static_cast<int>(matches.size());
    for (const FrameMatch& m : matches) {
      r.stats.searched += m.searched ? 1 : 0;
      r.stats.matched += m.matched ? 1 : 0;
      r.stats.updated += m.updated ? 1 : 0;
      r.stats.ransac_inliers += m.ransac_inlier ? 1 : 0;
    }
    for (const LandmarkReport& l : r.landmarks) r.stats.initialized += l.created_now ? 1 : 0;
  }
  return r;
}

Nis frame_nis(const std::vector<FrameMatch>& matches) {
  Nis n;
  for (const FrameMatch& m : matches) {
    if (!m.updated) continue;
    const Eigen::LLT<Eigen::Matrix2d> llt(m.S);
    if (llt.info() != Eigen::Success) continue;
    const Eigen::Vector2d y = m.z - m.h;
    n.sum += y.dot(llt.solve(y));
    ++n.count;
  }
  return n;
}

}  // namespace rtslam::viz
