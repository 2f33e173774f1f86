#pragma once
// The System owns the frame loop (paper, section 2: the generic loop over robots, sensors and their data managers).
// It takes one time-ordered stream of sensor data (feed): proprioceptive inputs (IMU samples, odometry increments:
// any RawData whose sensor_id is a robot's input id) go to their robot at once (before its first start: IMU samples
// to the starters' window, replayed into the robot at the start, and of other types the latest one); every other datum waits until the inputs of every robot that needs them cover its time, then, in time order,
// it is offered to its robot's RobotStarter while the robot has not started, or goes through the filter: every robot
// of the map is predicted to the datum's time, the sensor's DataManager observes, corrects and initializes, the
// MapManager keeps the map clean. After each datum the HealthMonitor judges the filter; on a verdict (with
// health/reset) the landmarks are dropped and the robot starts again through its starter, in the same world frame
// (Robot::reanchor). Observers see every step.
//
// Ownership: fed data are owned objects. What the System is done with goes to a spare list that spare<T>() hands
// out again, so that a feeder allocates nothing per datum after warm-up (the per-frame path allocates nothing).
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rtslam/core/ring_buffer.hpp"
#include "rtslam/slam/health.hpp"
#include "rtslam/slam/managers.hpp"
#include "rtslam/slam/map.hpp"
#include "rtslam/slam/robot.hpp"

namespace rtslam::slam {

/// How a robot starts: its state and covariance at time t in the starter's own frame (the map's first start defines
/// the world frame; a restart is re-anchored at the robot's last healthy state by Robot::reanchor).
struct RobotStart {
  Eigen::VectorXd x;
  Eigen::MatrixXd P;
  TimeNs t = 0;
  std::string description;
  /// The data to process once started, in time order (the first one at t): the datum just offered and/or data the
  /// starter held back (a visual-inertial start's window). Valid until the starter is called again.
  std::vector<const RawData*> replay;
};

/// Starts a robot: offered its sensors' data (covered by its inputs) until it can say where the robot is.
class RobotStarter {
 public:
  virtual ~RobotStarter() = default;
  /// `inputs`: the robot's recent proprioceptive data, oldest first (empty for robots without inputs).
  virtual std::optional<RobotStart> offer(const RawData& datum, const RingBuffer<ImuData>& inputs) = 0;
  /// The robot is now in the map at the start's time (first: the map's first start of this robot).
  virtual void started(Map& /*map*/, Robot& /*robot*/, bool /*first*/) {}
  /// The health monitor reset the robot: it will be offered data again.
  virtual void restart() {}
  /// Data offered and dropped so far (not replayed into the filter).
  virtual int skipped() const { return 0; }
  /// While the robot has not started: what the starter still needs, for the message of a run that ends before the
  /// start (e.g. "0.50 s of IMU data before an image (imu/init_window)"); empty when nothing in particular.
  virtual std::string waiting_for() const { return {}; }
};

/// What an observer sees after each datum the filter processed. References are valid during the call only.
struct StepReport {
  long index = 0;  // landmark sensors' data processed before this one (a stereo pair counts 2; stats.frame counts 1)
  const RawData& raw;
  const Map& map;
  const Robot& robot;    // the robot of the datum's sensor
  const Sensor& sensor;
  const FrameStats& stats;  // with the health verdict and the reset flag
  const std::string& verdict_reason;  // empty when healthy
};

/// Runs after each datum the filter processed, before the health verdict, with write access to the map: robot-level
/// corrections that are not a sensor's (e.g. zero-velocity updates). `inputs`: the robot's recent inputs.
class StepHook {
 public:
  virtual ~StepHook() = default;
  virtual void after_step(Map& map, Robot& robot, const Sensor& sensor, const RawData& raw,
                          const RingBuffer<ImuData>& inputs, FrameStats& stats) = 0;
};

class Observer {
 public:
  virtual ~Observer() = default;
  virtual void on_step(const StepReport& step) = 0;
  /// A robot (re)started (before its replayed data are processed).
  virtual void on_start(const Robot& /*robot*/, const RobotStart& /*start*/) {}
};

struct SystemOptions {
  HealthOptions health;
  std::size_t input_window = 2048;  // recent proprioceptive data kept per robot for its starter
  std::size_t max_pending = 200;    // data waiting for inputs before the stream is judged broken
  long max_steps = 0;               // stop processing after this many data (0: no limit)
};

class System {
 public:
  System(Map& map, std::unique_ptr<MapManager> map_manager, SystemOptions options = {});

  /// Adds a robot (not yet in the map: its starter puts it there) with its sensors. Its sensors get their ids now;
  /// its proprioceptive inputs are fed with sensor_id = the returned input id.
  int add_robot(std::unique_ptr<Robot> robot, std::unique_ptr<RobotStarter> starter);
  void add_observer(Observer& observer) { observers_.push_back(&observer); }
  /// The observers told of every step and (re)start, in the order added.
  const std::vector<Observer*>& observers() const { return observers_; }
  void add_hook(std::unique_ptr<StepHook> hook) { hooks_.push_back(std::move(hook)); }

  /// Feeds one datum (see the header comment). Throws DataError when time goes backwards within a stream, the
  /// sensor is unknown, or more than max_pending data wait for inputs.
  void feed(std::unique_ptr<RawData> datum);
  /// An object of type T the System is done with (its contents released), or a new one.
  template <class T>
  std::unique_ptr<T> spare() {
    for (std::size_t i = spares_.size(); i-- > 0;) {
      if (auto* p = dynamic_cast<T*>(spares_[i].get())) {
        spares_[i].release();
        spares_[i] = std::move(spares_.back());
        spares_.pop_back();
        return std::unique_ptr<T>(p);
      }
    }
    return std::make_unique<T>();
  }

  /// One datum through the filter now (its robot in the map): predict every robot, data manager, map manager.
  /// The loop's inner step, public for callers that drive robots themselves (tests).
  FrameStats process(const RawData& raw);

  /// Data of landmark-observing sensors processed (absolute fixes are not counted: they come between frames).
  long steps() const { return frame_; }
  bool finished() const { return options_.max_steps > 0 && frame_ >= options_.max_steps; }
  std::size_t pending() const { return pending_.size(); }
  /// The time of the oldest datum waiting for inputs.
  std::optional<TimeNs> first_pending() const {
    return pending_.empty() ? std::nullopt : std::optional<TimeNs>(pending_.front()->t);
  }
  Map& map() { return map_; }
  const Map& map() const { return map_; }

  /// Per-robot account (index in the order of add_robot).
  struct RobotCounts {
    int frames_lost = 0, frames_diverged = 0, resets = 0;
    Health final_health = Health::Ok;
    bool started = false;
    std::string start;  // the last start's description
  };
  std::size_t robot_count() const { return slots_.size(); }
  Robot& robot(std::size_t k) const { return *slots_[k].robot; }
  const RobotCounts& counts(std::size_t k) const { return slots_[k].counts; }
  const HealthMonitor& health(std::size_t k) const { return slots_[k].monitor; }

 private:
  struct Slot {
    explicit Slot(const SystemOptions& o) : monitor(o.health), recent(o.input_window) {}
    Robot* robot = nullptr;
    std::unique_ptr<Robot> waiting;  // the robot until its first start
    std::unique_ptr<RobotStarter> starter;
    int input_id = -1;
    HealthMonitor monitor;
    RingBuffer<ImuData> recent;
    std::optional<TimeNs> last_input_t;
    std::unique_ptr<RawData> latest_input;  // before the first start, the latest input that is not an ImuData
    bool restarting = false;
    Eigen::VectorXd last_good_x;
    RobotCounts counts;
  };
  Slot* slot_of_sensor(int sensor_id, const Sensor** sensor);
  /// The datum's time in the robots' clock: its stamp plus its sensor's time shift (Sensor::time_shift).
  TimeNs filter_time(const RawData& datum, const Sensor& sensor) const;
  /// The inputs of every robot that needs them cover the datum's filter time.
  bool covered(const RawData& datum);
  void handle(const RawData& datum);
  void start(Slot& slot, const RobotStart& s, const Sensor& sensor);
  void step(Slot& slot, const Sensor& sensor, const RawData& datum);
  void recycle(std::unique_ptr<RawData> datum);

  Map& map_;
  std::unique_ptr<MapManager> map_manager_;
  SystemOptions options_;
  std::vector<Slot> slots_;
  std::vector<Observer*> observers_;
  std::vector<std::unique_ptr<StepHook>> hooks_;
  RingBuffer<std::unique_ptr<RawData>> pending_;
  std::vector<std::unique_ptr<RawData>> spares_;
  long frame_ = 0;  // landmark sensors' data processed
  // The map's frame (FrameStats::frame): a landmark sensor's datum of another time or another robot starts the next.
  long map_frame_ = -1;
  TimeNs map_frame_t_ = 0;
  const Robot* map_frame_robot_ = nullptr;
};

}  // namespace rtslam::slam
