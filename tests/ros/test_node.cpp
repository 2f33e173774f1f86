// rtslam_ros against a ROS master on loopback: the suite starts `rosmaster` on 127.0.0.1 at a free port
// (ROS_MASTER_URI / ROS_IP on loopback, ROS_HOME in a temporary folder); each test starts the node as a process with
// a calibration and a configuration, publishes a few seconds of the simulator's images (and IMU samples for the
// inertial configuration), and checks what the node publishes: one nav_msgs/Odometry per processed image with the
// same poses as the pipeline run in this process on the same measurements (bit for bit), the world -> robot and
// robot -> camera transforms on /tf, and the map as PointCloud2. Then it stops the node with SIGINT (exit code 0,
// trajectory written). Skipped with a message without ROS or rosmaster.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "io/io_test_util.hpp"
#include "recorded_source.hpp"
#include "rtslam/io/trajectory_io.hpp"
#include "rtslam/io/writers.hpp"
#include "rtslam/pipeline/image_slam.hpp"
#if RTSLAM_TEST_HAVE_ROS
#include "ros_client.hpp"
#endif

namespace rtslam::ros_node {
namespace {

namespace fs = std::filesystem;

#if RTSLAM_TEST_HAVE_ROS

/// A free TCP port on 127.0.0.1 (bound, read back, released).
int free_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  socklen_t len = sizeof addr;
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
    if (fd >= 0) ::close(fd);
    return -1;
  }
  ::close(fd);
  return ntohs(addr.sin_port);
}

/// True once something accepts connections on 127.0.0.1:port (polls until `timeout_s`).
bool wait_for_port(int port, double timeout_s) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    addr.sin_port = htons(static_cast<std::uint16_t>(port));
    const bool ok = fd >= 0 && ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
    if (fd >= 0) ::close(fd);
    if (ok) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return false;
}

/// A child process with its output in a log file; stopped (SIGINT, then SIGKILL after a while) when destroyed.
class Child {
 public:
  Child(const std::vector<std::string>& argv, const std::string& log) : log_(log) {
    // Everything the child needs is prepared before fork(): between fork and exec only async-signal-safe calls.
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    pid_ = ::fork();
    if (pid_ == 0) {
      const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd >= 0) {
        ::dup2(fd, STDOUT_FILENO);
        ::dup2(fd, STDERR_FILENO);
        ::close(fd);
      }
      ::execv(args[0], args.data());
      ::_exit(127);
    }
  }
  ~Child() { stop(5.0); }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  /// Sends SIGINT and waits up to `timeout_s` (then SIGKILL). Returns the exit code, or -signal, or -1000.
  int stop(double timeout_s) { return finish(timeout_s, true); }
  /// Waits up to `timeout_s` for the process to exit by itself (then SIGKILL). Returns as stop().
  int wait(double timeout_s) { return finish(timeout_s, false); }
  std::string log() const { return io::test::read_text(log_); }

 private:
  int finish(double timeout_s, bool interrupt) {
    if (pid_ <= 0) return status_;
    if (interrupt) ::kill(pid_, SIGINT);
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    int st = 0;
    while (true) {
      const pid_t r = ::waitpid(pid_, &st, WNOHANG);
      if (r == pid_) break;
      if (std::chrono::steady_clock::now() > end) {
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, &st, 0);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    pid_ = -1;
    status_ = WIFEXITED(st) ? WEXITSTATUS(st) : WIFSIGNALED(st) ? -WTERMSIG(st) : -1000;
    return status_;
  }

  pid_t pid_ = -1;
  int status_ = -1000;
  std::string log_;
};

/// One ROS master on loopback for the suite, and the test's own node: roscpp connects a process to one master for
/// its lifetime, so both live as long as the suite.
class RosNode : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!fs::exists(RTSLAM_ROSMASTER)) return;
    std::string dir = (fs::temp_directory_path() / "rtslam_ros_node_XXXXXX").string();
    ASSERT_NE(::mkdtemp(dir.data()), nullptr);
    dir_ = dir;
    const int port = free_port();
    ASSERT_GT(port, 0);
    // Loopback only, logs in the temporary folder. The children (master, nodes) inherit the environment.
    ::setenv("ROS_MASTER_URI", ("http://127.0.0.1:" + std::to_string(port)).c_str(), 1);
    ::setenv("ROS_IP", "127.0.0.1", 1);
    ::unsetenv("ROS_HOSTNAME");
    ::setenv("ROS_HOME", dir_.c_str(), 1);
    ::setenv("ROS_LOG_DIR", dir_.c_str(), 1);
    master_ = new Child({RTSLAM_ROSMASTER, "--core", "-p", std::to_string(port), "-w", "2"}, dir_ + "/master.log");
    ASSERT_TRUE(wait_for_port(port, 30.0)) << "rosmaster did not start:\n" << master_->log();
    client_ = new ros_test::RosTestClient("rtslam_ros_test", "/cam0/image_raw", "/imu0", "/rtslam_ros/odom",
                                          "/rtslam_ros/map");
  }
  static void TearDownTestSuite() {
    delete client_;
    delete master_;
    client_ = nullptr;
    master_ = nullptr;
    if (!dir_.empty()) {
      std::error_code ec;
      fs::remove_all(dir_, ec);
    }
  }
  void SetUp() override {
    if (master_ == nullptr) {
      GTEST_SKIP() << "rosmaster not found (" << RTSLAM_ROSMASTER << "): scripts/deps.sh installs it";
    }
    ASSERT_NE(client_, nullptr) << "the suite's ROS master did not start";
    client_->clear();
  }

  /// Runs the node on `duration_s` of the simulator with the configuration `config`, publishing its images (and
  /// IMU samples for inertial configurations) in time order at about twice the real rate, and checks what the node
  /// publishes against the pipeline run in this process on the same measurements.
  static void expect_node_matches_the_pipeline(const std::string& config, double duration_s) {
    io::test::TempDir dir;
    pipeline::ImageSlamOptions o = pipeline::load_image_slam_config(RTSLAM_SOURCE_DIR "/" + config);
    o.sim_duration_s = duration_s;
    const bool inertial = o.robot == "inertial";
    io::Dataset sim = pipeline::make_sim_dataset(o);
    io::write_rig_yaml(dir / "rig.yaml", sim.rig);
    io::write_config_yaml(dir / "config.yaml", pipeline::to_yaml(o));
    const ros_test::Recorded recorded(*sim.source);
    std::size_t n_images = 0;
    for (const auto& m : recorded.measurements()) n_images += std::holds_alternative<io::ImageFrame>(m) ? 1 : 0;

    Child node({RTSLAM_ROS_NODE, "__name:=rtslam_ros", "_calibration:=" + (dir / "rig.yaml"),
                "_config:=" + (dir / "config.yaml"), "_trajectory:=" + (dir / "trajectory.txt"), "_camera_frame:=cam0",
                "_queue_size:=1000"},
               dir / "node.log");
    ASSERT_TRUE(client_->wait_for_subscribers(1, inertial, 60.0)) << "the node did not subscribe:\n" << node.log();
    ASSERT_TRUE(client_->wait_for_publishers(1, 60.0)) << "no connection to the node's publishers:\n" << node.log();
    TimeNs last_image = -1;
    for (const auto& m : recorded.measurements()) {
      if (!inertial && std::holds_alternative<io::ImuSample>(m)) continue;  // the node does not subscribe to it
      if (std::holds_alternative<io::ImageFrame>(m)) {
        if (last_image >= 0) std::this_thread::sleep_for(std::chrono::nanoseconds((io::time_of(m) - last_image) / 2));
        last_image = io::time_of(m);
      }
      client_->publish(m);
    }

    // The same measurements through the pipeline here (no ground truth: the node has none either).
    sim.source = recorded.replay();
    sim.ground_truth.reset();
    const pipeline::ImageSlamResult expected = pipeline::run_image_slam(sim, o);
    const std::size_t n = expected.estimate.poses.size();
    ASSERT_GT(n, 20u);
    EXPECT_EQ(n + static_cast<std::size_t>(expected.images_before_start + expected.images_not_covered), n_images);
    ASSERT_TRUE(client_->wait_for_odometry(n, 120.0))
        << client_->odometry().size() << " odometry messages for " << n << " processed images:\n"
        << node.log();
    EXPECT_EQ(node.stop(30.0), 0) << node.log();

    const std::vector<ros_test::ReceivedOdometry> odom = client_->odometry();
    ASSERT_EQ(odom.size(), n);
    for (std::size_t k = 0; k < n; ++k) {
      const StampedPose& e = expected.estimate.poses[k];
      EXPECT_EQ(odom[k].t, e.t) << "image " << k;
      EXPECT_EQ(odom[k].frame_id, "world");
      EXPECT_EQ(odom[k].child_frame_id, "base_link");
      EXPECT_EQ(odom[k].p, e.p_WR) << "image " << k;
      EXPECT_EQ(odom[k].q.coeffs(), e.q_WR.coeffs()) << "image " << k;
      const Eigen::Map<const Eigen::Matrix<double, 6, 6, Eigen::RowMajor>> cov(odom[k].pose_covariance.data());
      EXPECT_TRUE(cov.isApprox(cov.transpose(), 0.0)) << "image " << k;
      EXPECT_GE(cov.diagonal().minCoeff(), 0.0) << "image " << k;
    }
    std::size_t robot_tf = 0, camera_tf = 0;
    for (const auto& T : client_->transforms()) {
      robot_tf += T.parent == "world" && T.child == "base_link" ? 1 : 0;
      camera_tf += T.parent == "base_link" && T.child == "cam0" ? 1 : 0;
    }
    EXPECT_EQ(robot_tf, n);
    EXPECT_EQ(camera_tf, n);
    // The map topic keeps the newest clouds (publisher queue of 2): the visual-inertial start filters its buffered
    // window in one burst, whose older clouds may be dropped; the last one always arrives.
    EXPECT_LE(client_->map_messages(), n);
    EXPECT_GE(client_->map_messages(), 1u);
    EXPECT_EQ(client_->last_map_points(), static_cast<std::size_t>(expected.landmarks_final));
    EXPECT_EQ(client_->last_map_fields(), (std::vector<std::string>{"x", "y", "z", "id"}));
    EXPECT_EQ(io::read_trajectory(dir / "trajectory.txt").poses.size(), n);
  }

  static std::string dir_;  // ROS_HOME of the suite
  static Child* master_;
  static ros_test::RosTestClient* client_;
};

std::string RosNode::dir_;
Child* RosNode::master_ = nullptr;
ros_test::RosTestClient* RosNode::client_ = nullptr;

TEST_F(RosNode, MonocularOdometryTfAndMapForEveryImage) {
  expect_node_matches_the_pipeline("config/sim_mono.yaml", 1.5);
}

TEST_F(RosNode, InertialOdometryFromImagesAndImuOnTwoTopics) {
  expect_node_matches_the_pipeline("config/sim_mono_imu.yaml", 1.5);
}

TEST_F(RosNode, AMisspeltParameterStopsTheNodeWithOneLine) {
  io::test::TempDir dir;
  // Its own name: private parameters stay on the master after the node exits.
  Child node({RTSLAM_ROS_NODE, "__name:=rtslam_ros_typo", "_calibraton:=typo.yaml"}, dir / "node.log");
  EXPECT_EQ(node.wait(60.0), 1) << node.log();
  EXPECT_NE(node.log().find("unknown parameter /rtslam_ros_typo/calibraton"), std::string::npos) << node.log();
}

#else

TEST(RosNode, NeedsRos) {
  GTEST_SKIP() << "built without ROS1: the node is not built (scripts/deps.sh installs the packages, docs/ros.md)";
}

#endif

}  // namespace
}  // namespace rtslam::ros_node
