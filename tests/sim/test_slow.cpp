// Slow acceptance run (ctest label `slow`): the full high-dynamic preset, as `rtslam simulate --preset high-dynamic
// --out DIR` writes it, read back identically by the project's EuRoC reader.
#include <filesystem>
#include <numbers>

#include <unistd.h>

#include <gtest/gtest.h>

#include "rtslam/io/dataset.hpp"
#include "rtslam/sim/simulation.hpp"

namespace rtslam::sim {
namespace {

namespace fs = std::filesystem;

// The acceptance run of the issue: the full high-dynamic preset, written and read back identically.
// Label `slow`: ctest --test-dir build -L slow -R sim (a few minutes on 2 cores).
TEST(SimulationSlow, FullHighDynamicPresetReadsBackIdenticallyAndReachesTheExtremes) {
  const auto sim = Simulation::create(SimConfig::preset("high-dynamic"));
  double max_yaw_rate = 0.0, max_acc = 0.0;
  for (TimeNs t = sim->trajectory().t_begin(); t <= sim->image_times().back(); t += 1'000'000) {
    const KinematicState s = sim->trajectory().at(t);
    max_yaw_rate = std::max(max_yaw_rate, std::abs((s.q_WR * s.w_R).z()));
    max_acc = std::max(max_acc, s.a_WR.norm());
  }
  EXPECT_GE(max_yaw_rate, 400.0 * std::numbers::pi / 180.0);
  EXPECT_GE(max_acc, 3.0 * 9.81);
  const fs::path dir = fs::temp_directory_path() / ("rtslam_test_sim_full_hd_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  sim->write_euroc(dir.string());
  io::Dataset ds = io::open_dataset("euroc:" + dir.string());
  std::size_t n_img = 0, n_imu = 0;
  while (auto m = ds.source->next()) {
    if (const auto* f = std::get_if<io::ImageFrame>(&*m)) {
      // Re-render every 20th frame (rendering all twice would double the run time); check the others' format.
      ASSERT_EQ(f->t, sim->image_times()[n_img]);
      ASSERT_EQ(f->image.size(), cv::Size(752, 480));
      if (n_img % 20 == 0) {
        ASSERT_EQ(cv::norm(f->image, sim->render_image(n_img), cv::NORM_INF), 0.0) << n_img;
      }
      ++n_img;
    } else {
      const auto& s = std::get<io::ImuSample>(*m);
      ASSERT_TRUE(s.accel == sim->imu_samples()[n_imu].accel && s.gyro == sim->imu_samples()[n_imu].gyro);
      ++n_imu;
    }
  }
  EXPECT_EQ(n_img, sim->image_times().size());
  EXPECT_EQ(n_imu, sim->imu_samples().size());
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rtslam::sim
