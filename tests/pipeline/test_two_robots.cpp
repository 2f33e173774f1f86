// Two robots in one world (issue 15 item 4): two odometry-driven robots, each with its own hand-held trajectory,
// odometry and camera in the simulator's room, run in ONE map built by the builder (Registry::add_robot_to): the
// landmarks are the map's, so a landmark one robot's camera initialized is searched and corrected in the other's.
// The common world frame: each robot starts at its known start pose with zero covariance (a configured start, as a
// user with surveyed start poses would give; the estimator reads no ground truth while running). Acceptance: both
// robots' position errors (ATE, no alignment: the frame is given) are lower than each robot's alone on the same
// data with the same seeds.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>

#include "rtslam/eval/metrics.hpp"
#include "rtslam/pipeline/builder.hpp"
#include "rtslam/pipeline/starters.hpp"
#include "rtslam/sim/simulation.hpp"
#include "rtslam/slam/odometry_robot.hpp"

namespace rtslam::pipeline {
namespace {

const std::string kTwoRobotsConfig = RTSLAM_SOURCE_DIR "/config/sim_mono.yaml";

struct RobotData {
  std::shared_ptr<const sim::Simulation> sim;
  std::unique_ptr<io::Source> source;
  std::optional<io::Measurement> next;
  BuiltRobot built;
  Trajectory estimate;
};

std::shared_ptr<const sim::Simulation> make_robot_sim(std::uint64_t trajectory_seed, double duration_s) {
  sim::SimConfig sc = sim::SimConfig::load("handheld");  // the room; both robots see the same world
  sc.seed = trajectory_seed;
  sc.trajectory_seed = trajectory_seed;
  sc.duration_s = duration_s;
  sc.imu_enabled = false;
  sc.odometry.enabled = true;
  return sim::Simulation::create(sc);
}

// Each robot's estimate after each of its images.
struct Collector final : slam::Observer {
  std::map<const slam::Robot*, Trajectory*> out;
  void on_step(const slam::StepReport& s) override {
    StampedPose p;
    p.t = s.raw.t;
    const math::Pose T = s.robot.pose();
    p.p_WR = T.p;
    p.q_WR = T.q;
    out.at(&s.robot)->poses.push_back(p);
  }
};

// Runs the robots of `sims` in one map (one robot: alone) and returns each one's estimate.
std::vector<Trajectory> run(const std::vector<std::shared_ptr<const sim::Simulation>>& sims) {
  ImageSlamOptions o = load_image_slam_config(kTwoRobotsConfig);
  o.robot = "odometry";
  std::vector<RobotData> robots(sims.size());
  std::vector<BuildContext> contexts;
  contexts.reserve(sims.size());
  BuiltSystem built;
  Collector collector;
  for (std::size_t k = 0; k < sims.size(); ++k) {
    RobotData& r = robots[k];
    r.sim = sims[k];
    r.source = r.sim->make_source();
    r.next = r.source->next();
    // The known start pose in the common world frame: configuration, read before the run.
    const sim::KinematicState s0 = r.sim->trajectory().at(r.sim->image_times().front());
    Eigen::VectorXd x0(7);
    x0 << s0.p_WR, s0.q_WR.w(), s0.q_WR.x(), s0.q_WR.y(), s0.q_WR.z();
    contexts.push_back(BuildContext{o, r.sim->rig(), "two robots", x0, Eigen::MatrixXd::Zero(6, 6)});
    if (k == 0) built = build_system(contexts.back());
    else Registry::builtin().add_robot_to(built, contexts.back());
    r.built = built.robots.back();
    collector.out[r.built.robot] = &r.estimate;
  }
  slam::System& system = *built.system;
  system.add_observer(collector);
  for (;;) {  // the streams merged in time order
    RobotData* first = nullptr;
    for (RobotData& r : robots) {
      if (r.next && (!first || io::time_of(*r.next) < io::time_of(*first->next))) first = &r;
    }
    if (!first) break;
    if (const auto* odo = std::get_if<io::OdometrySample>(&*first->next)) {
      auto d = system.spare<slam::OdometryData>();
      d->t = odo->t;
      d->t_from = odo->t_from;
      d->sensor_id = first->built.input_id;
      d->dp = odo->dp;
      d->dtheta = odo->dtheta;
      system.feed(std::move(d));
    } else if (auto* img = std::get_if<io::ImageFrame>(&*first->next)) {
      auto d = system.spare<MatImage>();
      d->set(img->t, first->built.cameras.front().sensor->id(), std::move(img->image));
      system.feed(std::move(d));
    }
    first->next = first->source->next();
  }
  std::vector<Trajectory> out;
  for (RobotData& r : robots) out.push_back(std::move(r.estimate));
  return out;
}

double ate(const Trajectory& est, const sim::Simulation& sim) {
  eval::EvalOptions eo;
  eo.align = eval::Alignment::None;
  eo.with_rpe = false;
  return eval::evaluate(est, sim.ground_truth(), eo).ate.trans_m.rmse;
}

TEST(TwoRobots, SharedLandmarksLowerBothPoseErrors) {
  const double duration_s = 10.0;
  const auto a = make_robot_sim(11, duration_s);
  const auto b = make_robot_sim(12, duration_s);
  const double a_alone = ate(run({a}).front(), *a);
  const double b_alone = ate(run({b}).front(), *b);
  const std::vector<Trajectory> both = run({a, b});
  const double a_joint = ate(both[0], *a), b_joint = ate(both[1], *b);
  std::printf("ATE (no alignment): robot A alone %.4f m, in the shared map %.4f m; robot B alone %.4f m, shared "
              "%.4f m\n",
              a_alone, a_joint, b_alone, b_joint);
  EXPECT_LT(a_joint, a_alone);
  EXPECT_LT(b_joint, b_alone);
}

}  // namespace
}  // namespace rtslam::pipeline
