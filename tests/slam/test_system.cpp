// The System's frame loop (slam/system.hpp) with stand-in strategies: routing of inputs and sensor data, data held
// until the IMU covers them, starts through a RobotStarter with replayed data, observers, the health monitor's reset
// and re-start in the same world frame, max_steps, reuse of fed objects, and the errors of a broken stream.
#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"
#include "rtslam/slam/absolute_sensor.hpp"
#include "rtslam/slam/sensor.hpp"
#include "rtslam/slam/system.hpp"
#include "slam/system_doubles.hpp"
#include "support/test_camera.hpp"

namespace rtslam::slam {
namespace {

// Adds a sensor to `robot` with a counting data manager; returns the manager.
CountingDataManager& add_counted(Robot& robot, std::unique_ptr<Sensor> sensor) {
  Sensor& s = robot.add_sensor(std::move(sensor));
  auto dm = std::make_unique<CountingDataManager>();
  CountingDataManager& counting = *dm;
  s.set_data_manager(std::move(dm));
  return counting;
}

// Starts at the `start_at`-th offered datum, replaying the data it held since the first offer (as a
// visual-inertial start replays its window); the held copies are its own.
class WindowStarter final : public RobotStarter {
 public:
  WindowStarter(int start_at, int state_size, int tangent_size)
      : start_at_(start_at), x0_(Eigen::VectorXd::Zero(state_size)), P0_(Eigen::MatrixXd::Zero(tangent_size, tangent_size)) {
    x0_.segment<4>(3) << 1.0, 0.0, 0.0, 0.0;
  }
  std::optional<RobotStart> offer(const RawData& datum, const RingBuffer<ImuData>& inputs) override {
    ++offers;
    inputs_seen = inputs.size();
    held_.push_back(std::make_unique<Blob>());
    held_.back()->t = datum.t;
    held_.back()->sensor_id = datum.sensor_id;
    if (static_cast<int>(held_.size()) < start_at_) return std::nullopt;
    RobotStart s;
    s.x = x0_;
    s.P = P0_;
    s.t = held_.front()->t;
    s.description = "window start";
    for (const auto& h : held_) s.replay.push_back(h.get());
    return s;
  }
  void started(Map&, Robot&, bool first) override { first ? ++first_starts : ++restarts_seen; }
  void restart() override {
    ++restart_calls;
    held_.clear();
  }
  int offers = 0, first_starts = 0, restarts_seen = 0, restart_calls = 0;
  std::size_t inputs_seen = 0;
  Eigen::VectorXd x0_start() const { return x0_; }
  void set_x0(const Eigen::VectorXd& x) { x0_ = x; }

 private:
  int start_at_;
  Eigen::VectorXd x0_;
  Eigen::MatrixXd P0_;
  std::vector<std::unique_ptr<Blob>> held_;
};

struct Recorder final : Observer {
  void on_step(const StepReport& s) override {
    indices.push_back(s.index);
    times.push_back(s.raw.t);
    health.push_back(s.stats.health);
    landmark_frame.push_back(s.stats.landmark_frame);
    resets += s.stats.reset ? 1 : 0;
  }
  void on_start(const Robot&, const RobotStart& s) override { starts.push_back(s.t); }
  std::vector<long> indices;
  std::vector<TimeNs> times, starts;
  std::vector<int> health;
  std::vector<bool> landmark_frame;
  int resets = 0;
};


struct InertialRig {
  World world;
  Map* map = nullptr;
  std::unique_ptr<System> system;
  CountingDataManager* dm = nullptr;
  WindowStarter* starter = nullptr;
  Sensor* camera = nullptr;
  Sensor* gps = nullptr;  // with_gps: an absolute position sensor with a counting data manager
  CountingDataManager* gps_dm = nullptr;
  int imu_id = -1;
  Recorder recorder;
  explicit InertialRig(int start_at, SystemOptions so = {}, bool with_gps = false) {
    map = &world.add_map();
    system = std::make_unique<System>(*map, std::make_unique<NoMapManager>(), so);
    auto robot = std::make_unique<InertialRobot>(models::InertialParams{});
    camera = &robot->add_sensor(std::make_unique<PinholeSensor>("cam0", support::vga_camera(), math::Pose{}));
    auto dm_ptr = std::make_unique<CountingDataManager>();
    dm = dm_ptr.get();
    camera->set_data_manager(std::move(dm_ptr));
    if (with_gps) {
      gps = &robot->add_sensor(std::make_unique<AbsoluteSensor>("gps", AbsoluteSensor::Kind::Position, math::Pose{}));
      auto g = std::make_unique<CountingDataManager>();
      gps_dm = g.get();
      gps->set_data_manager(std::move(g));
    }
    auto st = std::make_unique<WindowStarter>(start_at, 19, 18);
    st->set_x0([] {
      Eigen::VectorXd x = Eigen::VectorXd::Zero(19);
      x.segment<4>(3) << 1.0, 0.0, 0.0, 0.0;
      x.segment<3>(16) << 0.0, 0.0, -9.81;
      return x;
    }());
    starter = st.get();
    imu_id = system->add_robot(std::move(robot), std::move(st));
    system->add_observer(recorder);
  }
  void imu(TimeNs t) {
    auto d = system->spare<ImuData>();
    d->t = t;
    d->sensor_id = imu_id;
    d->m.accel = Eigen::Vector3d(0.0, 0.0, 9.81);
    system->feed(std::move(d));
  }
  void image(TimeNs t) {
    auto d = system->spare<Blob>();
    d->t = t;
    d->sensor_id = camera->id();
    system->feed(std::move(d));
  }
  void fix(TimeNs t) {
    auto d = system->spare<PositionData>();
    d->t = t;
    d->sensor_id = gps->id();
    system->feed(std::move(d));
  }
};

TEST(System, SensorsHaveIdsBeforeTheRobotIsInTheMapAndInputsTheirOwn) {
  InertialRig rig(1);
  EXPECT_GE(rig.camera->id(), 0);
  EXPECT_NE(rig.imu_id, rig.camera->id());
  EXPECT_TRUE(rig.map->robots().empty());  // the starter puts it there
}

TEST(System, ImagesWaitUntilTheImuCoversThemThenGoThroughTheStarterAndTheFilterInOrder) {
  InertialRig rig(/*start_at=*/3);
  for (int k = 0; k <= 10; ++k) rig.imu(k * 5 * kNsPerMs);  // IMU up to 50 ms
  rig.image(40 * kNsPerMs);
  rig.image(60 * kNsPerMs);  // not covered yet
  rig.image(80 * kNsPerMs);
  EXPECT_EQ(rig.starter->offers, 1);
  EXPECT_EQ(rig.system->pending(), 2u);
  EXPECT_TRUE(rig.map->robots().empty());
  // to 80 ms: both covered (an input at the image time first)
  for (int k = 11; k <= 16; ++k) rig.imu(k * 5 * kNsPerMs);
  EXPECT_EQ(rig.system->pending(), 0u);
  EXPECT_EQ(rig.starter->offers, 3);
  EXPECT_EQ(rig.starter->first_starts, 1);
  EXPECT_EQ(rig.starter->inputs_seen, 17u);
  ASSERT_EQ(rig.map->robots().size(), 1u);
  // The start is at the window's first image; its three images are processed in order.
  ASSERT_EQ(rig.recorder.starts.size(), 1u);
  EXPECT_EQ(rig.recorder.starts[0], 40 * kNsPerMs);
  EXPECT_EQ(rig.dm->times, (std::vector<TimeNs>{40 * kNsPerMs, 60 * kNsPerMs, 80 * kNsPerMs}));
  EXPECT_EQ(rig.recorder.indices, (std::vector<long>{0, 1, 2}));
  EXPECT_EQ(rig.system->steps(), 3);
  EXPECT_EQ(rig.map->robots()[0]->time(), 80 * kNsPerMs);
  // After the start every image goes straight to the filter once covered.
  rig.imu(85 * kNsPerMs);
  rig.image(85 * kNsPerMs);
  EXPECT_EQ(rig.dm->times.back(), 85 * kNsPerMs);
  EXPECT_EQ(rig.starter->offers, 3);
}

// Absolute fixes (a sensor that observes no landmark): before the robot started they are neither offered to the
// starter nor held for its replay (nothing to correct yet); after it they wait for the IMU like images, are processed
// by their data manager in time order and reported, but are no frame of their own (the frame index counts images).
TEST(System, AbsoluteFixesBeforeTheStartAreSkippedAndAfterItAreNoFrames) {
  InertialRig rig(/*start_at=*/2, {}, /*with_gps=*/true);
  for (int k = 0; k <= 10; ++k) rig.imu(k * 5 * kNsPerMs);  // IMU up to 50 ms
  rig.fix(10 * kNsPerMs);
  rig.image(20 * kNsPerMs);
  rig.fix(30 * kNsPerMs);
  EXPECT_EQ(rig.starter->offers, 1);  // the image only
  EXPECT_TRUE(rig.map->robots().empty());
  rig.image(40 * kNsPerMs);  // the start, at 20 ms, replays both images and no fix
  ASSERT_EQ(rig.map->robots().size(), 1u);
  EXPECT_EQ(rig.starter->offers, 2);
  EXPECT_EQ(rig.dm->times, (std::vector<TimeNs>{20 * kNsPerMs, 40 * kNsPerMs}));
  EXPECT_TRUE(rig.gps_dm->times.empty());
  rig.fix(45 * kNsPerMs);
  rig.image(50 * kNsPerMs);
  rig.fix(60 * kNsPerMs);  // not covered by the IMU yet: held
  EXPECT_EQ(rig.system->pending(), 1u);
  EXPECT_EQ(rig.gps_dm->times, (std::vector<TimeNs>{45 * kNsPerMs}));
  for (int k = 11; k <= 13; ++k) rig.imu(k * 5 * kNsPerMs);
  rig.image(65 * kNsPerMs);
  EXPECT_EQ(rig.system->pending(), 0u);
  EXPECT_EQ(rig.gps_dm->times, (std::vector<TimeNs>{45 * kNsPerMs, 60 * kNsPerMs}));
  EXPECT_EQ(rig.dm->times, (std::vector<TimeNs>{20 * kNsPerMs, 40 * kNsPerMs, 50 * kNsPerMs, 65 * kNsPerMs}));
  EXPECT_EQ(rig.dm->frames, (std::vector<long>{0, 1, 2, 3}));  // images keep consecutive frame numbers
  EXPECT_EQ(rig.recorder.times, (std::vector<TimeNs>{20 * kNsPerMs, 40 * kNsPerMs, 45 * kNsPerMs, 50 * kNsPerMs,
                                                     60 * kNsPerMs, 65 * kNsPerMs}));
  EXPECT_EQ(rig.recorder.landmark_frame, (std::vector<bool>{true, true, false, true, false, true}));
  EXPECT_EQ(rig.starter->offers, 2);
  EXPECT_EQ(rig.recorder.resets, 0);
}

TEST(System, FedObjectsAreReusedAndReleased) {
  InertialRig rig(1);
  rig.imu(0);
  auto d = rig.system->spare<Blob>();
  Blob* first = d.get();
  d->t = 0;
  d->sensor_id = rig.camera->id();
  rig.system->feed(std::move(d));
  EXPECT_TRUE(first->released);
  auto again = rig.system->spare<Blob>();
  EXPECT_EQ(again.get(), first);  // the same object: no allocation per datum
  auto imu = rig.system->spare<ImuData>();
  EXPECT_NE(imu.get(), nullptr);
}

TEST(System, BrokenStreamsAreErrors) {
  {
    InertialRig rig(1);
    rig.imu(10 * kNsPerMs);
    EXPECT_THROW(rig.imu(10 * kNsPerMs), DataError);  // not after the previous input
  }
  {
    InertialRig rig(1);
    auto d = rig.system->spare<Blob>();
    d->sensor_id = 999;
    EXPECT_THROW(rig.system->feed(std::move(d)), DataError);  // unknown sensor
  }
  {
    SystemOptions so;
    so.max_pending = 5;
    InertialRig rig(1, so);
    for (int k = 0; k < 5; ++k) rig.image(k * kNsPerMs);  // no IMU at all: everything waits
    EXPECT_EQ(rig.system->pending(), 5u);
    EXPECT_THROW(rig.image(6 * kNsPerMs), DataError);
  }
}

TEST(System, MaxStepsStopsTheFilter) {
  SystemOptions so;
  so.max_steps = 2;
  InertialRig rig(1, so);
  for (int k = 0; k <= 20; ++k) rig.imu(k * 5 * kNsPerMs);
  for (int k = 0; k < 5; ++k) rig.image(k * 20 * kNsPerMs);
  EXPECT_EQ(rig.system->steps(), 2);
  EXPECT_TRUE(rig.system->finished());
  EXPECT_EQ(rig.dm->times.size(), 2u);
}

TEST(System, AHealthVerdictResetsTheMapAndRestartsTheRobotAtItsLastHealthyPose) {
  SystemOptions so;
  so.health.grace_s = 0.0;
  so.health.lost_after_s = 0.05;
  so.health.min_updated = 3;
  InertialRig rig(1, so);
  for (int k = 0; k <= 100; ++k) rig.imu(k * 5 * kNsPerMs);  // 0.5 s
  rig.image(0);
  rig.image(20 * kNsPerMs);
  ASSERT_EQ(rig.map->robots().size(), 1u);
  const Robot& robot = *rig.map->robots()[0];
  const Eigen::Vector3d p_healthy = robot.pose().p;
  rig.dm->updated = 0;  // tracking collapses: no correction any more
  for (int k = 2; k < 10 && rig.recorder.resets == 0; ++k) rig.image(k * 20 * kNsPerMs);
  ASSERT_EQ(rig.recorder.resets, 1);
  EXPECT_EQ(rig.starter->restart_calls, 1);
  EXPECT_EQ(rig.system->counts(0).resets, 1);
  EXPECT_EQ(rig.system->counts(0).frames_lost, 1);
  EXPECT_EQ(rig.recorder.health.back(), static_cast<int>(Health::Lost));
  // The next image goes to the starter again; the restart keeps the world frame (re-anchored at the last healthy
  // pose, not at the starter's origin).
  rig.dm->updated = 10;
  Eigen::VectorXd elsewhere = rig.starter->x0_start();
  elsewhere.head<3>() << 5.0, 0.0, 0.0;  // where the starter alone would put the robot
  rig.starter->set_x0(elsewhere);
  const int offers = rig.starter->offers;
  rig.image(300 * kNsPerMs);
  EXPECT_EQ(rig.starter->offers, offers + 1);
  EXPECT_EQ(rig.starter->restarts_seen, 1);
  EXPECT_EQ(rig.map->robots().size(), 1u);
  EXPECT_LT((robot.pose().p - p_healthy).norm(), 1e-12);
}

TEST(System, RobotsWithoutInputsProcessAtOnce) {
  World world;
  Map& map = world.add_map();
  System system(map, std::make_unique<NoMapManager>());
  auto robot = std::make_unique<ConstantVelocityRobot>(models::ConstantVelocityParams{});
  CountingDataManager& counting =
      add_counted(*robot, std::make_unique<PinholeSensor>("cam0", support::vga_camera(), math::Pose{}));
  const Sensor& cam = *robot->sensors()[0];
  const int input = system.add_robot(std::move(robot), std::make_unique<WindowStarter>(1, 13, 12));
  auto d = system.spare<Blob>();
  d->t = 5 * kNsPerMs;
  d->sensor_id = cam.id();
  system.feed(std::move(d));
  EXPECT_EQ(counting.times, std::vector<TimeNs>{5 * kNsPerMs});
  EXPECT_EQ(system.pending(), 0u);
  auto imu = system.spare<ImuData>();
  imu->t = 6 * kNsPerMs;
  imu->sensor_id = input;
  EXPECT_THROW(system.feed(std::move(imu)), DataError);  // a constant-velocity robot takes no input
}

// Frames count one robot's image times, not images (FrameStats::frame, the map manager's unit): the two images of a
// stereo pair share one; the next time starts the next, and so does another robot's image of the same time; an
// absolute fix between them starts none. The report's index still counts the images.
TEST(System, AStereoPairIsOneFrame) {
  World world;
  Map& map = world.add_map();
  System system(map, std::make_unique<NoMapManager>());
  auto robot = std::make_unique<ConstantVelocityRobot>(models::ConstantVelocityParams{});
  CountingDataManager& c0 =
      add_counted(*robot, std::make_unique<PinholeSensor>("cam0", support::vga_camera(), math::Pose{}));
  CountingDataManager& c1 =
      add_counted(*robot, std::make_unique<PinholeSensor>("cam1", support::vga_camera(), math::Pose{}));
  CountingDataManager& cg =
      add_counted(*robot, std::make_unique<AbsoluteSensor>("gps", AbsoluteSensor::Kind::Position, math::Pose{}));
  const Sensor &cam0 = *robot->sensors()[0], &cam1 = *robot->sensors()[1], &gps = *robot->sensors()[2];
  system.add_robot(std::move(robot), std::make_unique<WindowStarter>(1, 13, 12));
  auto other = std::make_unique<ConstantVelocityRobot>(models::ConstantVelocityParams{});
  CountingDataManager& c2 =
      add_counted(*other, std::make_unique<PinholeSensor>("other", support::vga_camera(), math::Pose{}));
  const Sensor& cam2 = *other->sensors()[0];
  system.add_robot(std::move(other), std::make_unique<WindowStarter>(1, 13, 12));
  Recorder recorder;
  system.add_observer(recorder);
  auto feed = [&](const Sensor& s, TimeNs t) {
    auto d = system.spare<Blob>();
    d->t = t * kNsPerMs;
    d->sensor_id = s.id();
    system.feed(std::move(d));
  };
  feed(cam0, 10);
  feed(cam1, 10);
  feed(gps, 15);
  feed(cam1, 20);  // either camera may come first
  feed(cam0, 20);
  feed(cam0, 30);  // a time with one image only
  feed(cam0, 40);
  feed(cam1, 40);
  feed(cam2, 40);  // the other robot, same time: its own frame
  feed(cam0, 50);
  EXPECT_EQ(c0.frames, (std::vector<long>{0, 1, 2, 3, 5}));
  EXPECT_EQ(c1.frames, (std::vector<long>{0, 1, 3}));
  EXPECT_EQ(c2.frames, (std::vector<long>{4}));
  EXPECT_EQ(cg.frames, (std::vector<long>{0}));  // between frames 0 and 1: in frame 0's
  EXPECT_EQ(recorder.indices, (std::vector<long>{0, 1, 2, 2, 3, 4, 5, 6, 7, 8}));
  EXPECT_EQ(system.steps(), 9);
}

}  // namespace
}  // namespace rtslam::slam
