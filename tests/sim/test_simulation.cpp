// Whole simulations: EuRoC folder output read back identically by the project's reader, deterministic bytes for a
// seed, the in-memory stream, presets and their YAML files, following real trajectories.
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <numbers>
#include <type_traits>
#include <variant>

#include <unistd.h>

#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/io/trajectory_io.hpp"
#include "rtslam/sim/simulation.hpp"
#include "support/temp_dir.hpp"

namespace rtslam::sim {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir(const std::string& name) { return ::rtslam::support::fresh_temp_dir("test_sim", name, false); }

std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// All regular files under `root` with their contents, by relative path.
std::map<std::string, std::string> folder_contents(const fs::path& root) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.is_regular_file()) out[fs::relative(e.path(), root).string()] = read_bytes(e.path());
  return out;
}

// The high-dynamic preset, shortened and cheaper to render for a unit test (the full preset: test_sim_slow).
SimConfig short_high_dynamic(double duration_s = 0.4) {
  SimConfig c = SimConfig::preset("high-dynamic");
  c.duration_s = duration_s;
  c.world.texel_size = 0.01;
  c.render.supersampling = 1;
  return c;
}

TEST(Simulation, EurocFolderReadsBackIdentically) {
  const auto sim = Simulation::create(short_high_dynamic());
  const fs::path dir = temp_dir("readback");
  sim->write_euroc(dir.string());
  ASSERT_TRUE(fs::exists(dir / "groundtruth.txt"));
  ASSERT_TRUE(fs::exists(dir / "mav0/state_groundtruth_estimate0/data.csv"));

  io::Dataset ds = io::open_dataset("euroc:" + dir.string());
  ASSERT_EQ(ds.rig.cameras.size(), 1u);
  const io::CameraCalibration& cam = ds.rig.cameras[0];
  const io::CameraCalibration& ref = sim->config().camera;
  EXPECT_EQ(cam.width, ref.width);
  EXPECT_EQ(cam.height, ref.height);
  EXPECT_EQ(cam.fx, ref.fx);
  EXPECT_EQ(cam.cy, ref.cy);
  EXPECT_EQ(cam.distortion_coeffs, ref.distortion_coeffs);
  EXPECT_EQ(cam.rate_hz, 50.0);
  EXPECT_TRUE(cam.T_RS.matrix() == ref.T_RS.matrix());
  ASSERT_TRUE(ds.rig.imu.has_value());
  EXPECT_EQ(ds.rig.imu->accel_noise_density, sim->config().imu.noise.accel_noise_density);
  EXPECT_EQ(ds.rig.imu->gyro_random_walk, sim->config().imu.noise.gyro_random_walk);

  std::size_t n_imu = 0, n_img = 0;
  while (auto m = ds.source->next()) {
    if (const auto* imu = std::get_if<io::ImuSample>(&*m)) {
      ASSERT_LT(n_imu, sim->imu_samples().size());
      const SynthImuSample& s = sim->imu_samples()[n_imu++];
      EXPECT_EQ(imu->t, s.t);
      EXPECT_TRUE(imu->gyro == s.gyro) << n_imu;
      EXPECT_TRUE(imu->accel == s.accel) << n_imu;
    } else {
      const auto& f = std::get<io::ImageFrame>(*m);
      ASSERT_LT(n_img, sim->image_times().size());
      EXPECT_EQ(f.t, sim->image_times()[n_img]);
      EXPECT_EQ(cv::norm(f.image, sim->render_image(n_img), cv::NORM_INF), 0.0) << "image " << n_img;
      ++n_img;
    }
  }
  EXPECT_EQ(n_imu, sim->imu_samples().size());
  EXPECT_EQ(n_img, sim->image_times().size());
  EXPECT_EQ(n_img, 21u);  // 0.4 s at 50 Hz, both ends included
  EXPECT_EQ(n_imu, 81u);

  ASSERT_TRUE(ds.ground_truth.has_value());
  const auto& gt = ds.ground_truth->poses;
  const auto& truth = sim->ground_truth().poses;
  ASSERT_EQ(gt.size(), truth.size());
  for (std::size_t i = 0; i < gt.size(); ++i) {
    EXPECT_EQ(gt[i].t, truth[i].t);
    EXPECT_TRUE(gt[i].p_WR == truth[i].p_WR) << i;
    EXPECT_TRUE(gt[i].q_WR.coeffs() == truth[i].q_WR.coeffs()) << i;
    ASSERT_TRUE(gt[i].v_WR && gt[i].accel_bias && gt[i].gyro_bias);
    EXPECT_TRUE(*gt[i].v_WR == *truth[i].v_WR) << i;
    EXPECT_TRUE(*gt[i].accel_bias == *truth[i].accel_bias) << i;
    EXPECT_TRUE(*gt[i].gyro_bias == *truth[i].gyro_bias) << i;
  }
  // groundtruth.txt (TUM) carries the same poses.
  const Trajectory tum = io::read_trajectory((dir / "groundtruth.txt").string());
  ASSERT_EQ(tum.poses.size(), truth.size());
  EXPECT_EQ(tum.poses.back().t, truth.back().t);
  EXPECT_LT((tum.poses.back().p_WR - truth.back().p_WR).norm(), 1e-9);
  fs::remove_all(dir);
}

TEST(Simulation, SameSeedGivesTheSameBytesAndAnotherSeedDoesNot) {
  SimConfig c = short_high_dynamic(0.1);
  const fs::path a = temp_dir("det_a"), b = temp_dir("det_b"), d = temp_dir("det_d");
  Simulation::create(c)->write_euroc(a.string());
  Simulation::create(c)->write_euroc(b.string());
  c.seed = 2;
  c.trajectory_seed = 1;  // same motion, other noise
  Simulation::create(c)->write_euroc(d.string());
  const auto ca = folder_contents(a), cb = folder_contents(b), cd = folder_contents(d);
  ASSERT_GT(ca.size(), 10u);
  EXPECT_TRUE(ca == cb);
  ASSERT_EQ(ca.size(), cd.size());
  // Other seed: the images (pixel noise) and the IMU (noise, biases) differ; the motion itself does not.
  EXPECT_NE(ca.at("mav0/imu0/data.csv"), cd.at("mav0/imu0/data.csv"));
  int differing_images = 0;
  for (const auto& [path, bytes] : ca)
    if (path.find("cam0/data/") != std::string::npos && bytes != cd.at(path)) ++differing_images;
  EXPECT_EQ(differing_images, 6);
  const Trajectory ta = io::read_trajectory((a / "groundtruth.txt").string());
  const Trajectory td = io::read_trajectory((d / "groundtruth.txt").string());
  EXPECT_TRUE(ta.poses.back().p_WR == td.poses.back().p_WR);
  for (const auto& p : {a, b, d}) fs::remove_all(p);
}

TEST(Simulation, InMemoryStreamIsTimeOrderedWithImuFirst) {
  SimConfig c = SimConfig::preset("handheld");
  c.duration_s = 0.5;
  c.world.texel_size = 0.01;
  c.render.supersampling = 1;
  const auto sim = Simulation::create(c);
  io::Dataset ds = sim->make_dataset();
  EXPECT_EQ(ds.kind, "sim");
  ASSERT_TRUE(ds.ground_truth.has_value());
  EXPECT_EQ(ds.source->image_count(), std::optional<std::size_t>(11));
  TimeNs last = std::numeric_limits<TimeNs>::min();
  bool last_was_image = false;
  std::size_t images = 0, imu = 0;
  while (auto m = ds.source->next()) {
    const TimeNs t = io::time_of(*m);
    EXPECT_GE(t, last);
    const bool is_image = std::holds_alternative<io::ImageFrame>(*m);
    if (t == last && !is_image) {
      EXPECT_FALSE(last_was_image) << "IMU after an image with the same timestamp";
    }
    if (is_image) {
      const auto& f = std::get<io::ImageFrame>(*m);
      EXPECT_EQ(f.image.type(), CV_8UC1);
      EXPECT_EQ(f.image.cols, 752);
      ++images;
    } else {
      ++imu;
    }
    last = t;
    last_was_image = is_image;
  }
  EXPECT_EQ(images, 11u);
  EXPECT_EQ(imu, 101u);
  EXPECT_EQ(ds.source->stats().images, 11u);
  // The handheld motion starts at rest: the first ground-truth velocity is zero, the first specific force is
  // gravity (plus the bias), the first image timestamp is the configured start time.
  EXPECT_LT(ds.ground_truth->poses.front().v_WR->norm(), 1e-12);
  EXPECT_EQ(sim->image_times().front(), from_seconds(1.0));
  const SynthImuSample& s0 = sim->imu_samples().front();
  EXPECT_NEAR((s0.accel - s0.accel_bias).norm(), 9.81, 0.1);
}

// Odometry (robots) and the absolute fixes (GPS, mocap) together: one time-ordered stream where, at equal
// timestamps, IMU samples come first, then odometry readings, images, GPS fixes and mocap poses; nothing is lost.
TEST(Simulation, InMemoryStreamOrdersOdometryAndAbsoluteFixes) {
  SimConfig c = SimConfig::preset("handheld");
  c.duration_s = 0.5;
  c.world.texel_size = 0.01;
  c.render.supersampling = 1;
  c.odometry.enabled = true;
  c.gps.enabled = true;
  c.mocap.enabled = true;
  const auto sim = Simulation::create(c);
  ASSERT_FALSE(sim->odometry().empty());
  ASSERT_FALSE(sim->gps_fixes().empty());
  ASSERT_FALSE(sim->mocap_fixes().empty());
  auto rank = [](const io::Measurement& m) {
    return std::visit(
        [](const auto& x) {
          using T = std::decay_t<decltype(x)>;
          if constexpr (std::is_same_v<T, io::ImuSample>) return 0;
          else if constexpr (std::is_same_v<T, io::OdometrySample>) return 1;
          else if constexpr (std::is_same_v<T, io::ImageFrame>) return 2;
          else if constexpr (std::is_same_v<T, io::PositionSample>) return 3;
          else return 4;
        },
        m);
  };
  std::unique_ptr<io::Source> src = sim->make_source();
  TimeNs last = std::numeric_limits<TimeNs>::min();
  int last_rank = -1;
  std::size_t counts[5] = {};
  bool some_tie = false;
  while (auto m = src->next()) {
    const TimeNs t = io::time_of(*m);
    const int r = rank(*m);
    ASSERT_GE(t, last);
    if (t == last) {
      EXPECT_GE(r, last_rank) << "at t = " << t;
      some_tie = some_tie || r != last_rank;
    }
    ++counts[r];
    last = t;
    last_rank = r;
  }
  EXPECT_TRUE(some_tie);
  EXPECT_EQ(counts[0], sim->imu_samples().size());
  EXPECT_EQ(counts[1], sim->odometry().size());
  EXPECT_EQ(counts[2], sim->image_times().size());
  EXPECT_EQ(counts[3], sim->gps_fixes().size());
  EXPECT_EQ(counts[4], sim->mocap_fixes().size());
}

TEST(Simulation, PresetFilesMatchTheBuiltInPresets) {
  for (const std::string& name : SimConfig::preset_names()) {
    const std::string file = RTSLAM_SOURCE_DIR "/config/sim/" + name + ".yaml";
    ASSERT_TRUE(fs::exists(file)) << file;
    const SimConfig a = SimConfig::preset(name), b = SimConfig::load(file);
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.trajectory, b.trajectory);
    EXPECT_EQ(a.ground_speed_mps, b.ground_speed_mps);
    EXPECT_EQ(a.odometry.enabled, b.odometry.enabled);
    EXPECT_EQ(a.duration_s, b.duration_s);
    EXPECT_EQ(a.seed, b.seed);
    EXPECT_EQ(a.camera.rate_hz, b.camera.rate_hz);
    EXPECT_EQ(a.camera.fx, b.camera.fx);
    EXPECT_EQ(a.render.supersampling, b.render.supersampling);
    EXPECT_EQ(a.render.noise_std, b.render.noise_std);
    EXPECT_EQ(a.render.exposure_s, b.render.exposure_s);
    EXPECT_EQ(a.imu.rate_hz, b.imu.rate_hz);
    EXPECT_EQ(a.imu.noise.gyro_noise_density, b.imu.noise.gyro_noise_density);
    EXPECT_EQ(a.imu.gyro_saturation_deg_s, b.imu.gyro_saturation_deg_s);
    EXPECT_EQ(a.world.room_size, b.world.room_size);
    EXPECT_EQ(a.world.boxes.size(), b.world.boxes.size());
    EXPECT_EQ(a.world.pillars.size(), b.world.pillars.size());
    EXPECT_EQ(a.world.random_boxes, b.world.random_boxes);
    EXPECT_EQ(a.world.texel_size, b.world.texel_size);
  }
  for (const std::string& name : WorldConfig::preset_names()) {
    const std::string file = RTSLAM_SOURCE_DIR "/config/sim/world_" + name + ".yaml";
    ASSERT_TRUE(fs::exists(file)) << file;
    const WorldConfig a = WorldConfig::preset(name), b = WorldConfig::from_file(file);
    EXPECT_EQ(a.room_size, b.room_size);
    ASSERT_EQ(a.boxes.size(), b.boxes.size());
    for (std::size_t i = 0; i < a.boxes.size(); ++i) EXPECT_EQ(a.boxes[i].center, b.boxes[i].center);
    EXPECT_EQ(a.pillars.size(), b.pillars.size());
  }
}

TEST(Simulation, ConfigurationErrorsNameTheKey) {
  const fs::path dir = temp_dir("cfg");
  fs::create_directories(dir);
  const fs::path f = dir / "bad.yaml";
  std::ofstream(f) << "base: handheld\nduration: 5\ncamera: {rate_hz: 30, gain: 2}\n";
  try {
    SimConfig::load(f.string());
    ADD_FAILURE() << "unknown key accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("gain"), std::string::npos) << e.what();
  }
  std::ofstream(f) << "base: handheld\ntrajectory: spiral\n";
  EXPECT_THROW(SimConfig::load(f.string()), ConfigError);
  std::ofstream(f) << "base: high-dynamic\nduration: 2\ncamera: {exposure: 0.5}\n";
  EXPECT_THROW(SimConfig::load(f.string()), ConfigError);
  EXPECT_THROW(SimConfig::load("no-such-preset"), ConfigError);
  // A synthetic trajectory that hits the walls of a too small room is refused.
  SimConfig c = SimConfig::preset("handheld");
  c.world.room_size = Eigen::Vector3d(1.5, 1.5, 2.0);
  c.world.boxes.clear();
  c.world.pillars.clear();
  EXPECT_THROW(Simulation::create(c), ConfigError);
  fs::remove_all(dir);
}

TEST(Simulation, FollowsARealEurocTrajectoryInsideAFittedRoom) {
  const std::string file = RTSLAM_SOURCE_DIR "/../shared/datasets/euroc-groundtruth/V2_01_easy.txt";
  if (!fs::exists(file)) GTEST_SKIP() << "dataset " << file << " not found";
  SimConfig c = SimConfig::preset("handheld");
  c.trajectory = "follow:" + file;
  c.duration_s = 20.0;
  c.world.texel_size = 0.01;
  c.render.supersampling = 1;
  const auto sim = Simulation::create(c);
  const Trajectory rec = io::read_trajectory(file);
  EXPECT_EQ(sim->image_times().front(), sim->trajectory().t_begin());
  EXPECT_GT(sim->image_times().front(), rec.poses.front().t);  // the spline starts one knot in
  for (const StampedPose& p : sim->ground_truth().poses) ASSERT_TRUE(sim->world().is_free(p.p_WR, 0.2));
  // The camera sees textured surfaces (not the inside of a box).
  cv::Scalar mean, stddev;
  cv::meanStdDev(sim->render_image(100), mean, stddev);
  EXPECT_GT(stddev[0], 15.0);
}

}  // namespace
}  // namespace rtslam::sim
