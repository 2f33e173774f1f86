// rtslam as a library: image SLAM on a dataset, or on the built-in simulator, with the calls `rtslam run` makes
// (apps/rtslam/cmd_run.cpp). Prints one line per processed image and the trajectory's length.
//
//   run_dataset [CONFIG.yaml] [DATASET] [--frames N]
//
// CONFIG.yaml: a configuration (the installed presets are in <prefix>/share/rtslam/config); without it, the
// simulator's built-in configuration. DATASET: a EuRoC/TUM/KITTI folder, an image folder, a video, a ROS bag or
// sim:PRESET; without it, the simulator. --frames N stops after N images.
#include <cstdlib>
#include <iostream>
#include <string>

#include <fmt/core.h>

#include "rtslam/core/error.hpp"
#include "rtslam/io/dataset.hpp"
#include "rtslam/pipeline/default_config.hpp"
#include "rtslam/pipeline/image_slam.hpp"

namespace {

rtslam::io::Dataset open(const std::string& dataset, const rtslam::pipeline::ImageSlamOptions& options) {
  if (dataset.empty()) return rtslam::pipeline::make_sim_dataset(options);
  rtslam::io::DatasetOptions dataset_options;
  dataset_options.use_imu = options.robot == "inertial";
  dataset_options.cameras = options.camera_indices();
  return rtslam::io::open_dataset(dataset, dataset_options);
}

int run(int argc, char** argv) {
  std::string config, dataset;
  int max_frames = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--frames" && i + 1 < argc) {
      max_frames = std::stoi(argv[++i]);
    } else if (arg.rfind("--", 0) != 0 && config.empty()) {
      config = arg;
    } else if (arg.rfind("--", 0) != 0 && dataset.empty()) {
      dataset = arg;
    } else {
      std::cerr << "usage: run_dataset [CONFIG.yaml] [DATASET] [--frames N]\n";
      return 2;
    }
  }

  // Options: the file over the defaults (unknown keys are errors), or the simulator's built-in configuration.
  rtslam::pipeline::ImageSlamOptions options =
      config.empty() ? rtslam::pipeline::default_sim_options() : rtslam::pipeline::load_image_slam_config(config);
  if (dataset.rfind("sim:", 0) == 0) {
    options.sim_preset = dataset.substr(4);
    dataset.clear();
  }
  if (max_frames > 0) options.max_frames = max_frames;
  options.validate();

  rtslam::io::Dataset data = open(dataset, options);
  if (!dataset.empty()) options = options.on_selected_cameras();  // the dataset's Rig holds those cameras only
  fmt::print("dataset: {} ({}), robot: {}\n", data.name, data.kind, options.robot);

  const rtslam::pipeline::ImageSlamResult result = rtslam::pipeline::run_image_slam(data, options);

  // Per processed image: time since the first one, map size, matches, corrections, new landmarks, wall time.
  fmt::print("{:>5} {:>8} {:>9} {:>7} {:>7} {:>4} {:>8}\n", "frame", "t [s]", "landmarks", "matched", "updated",
             "new", "time[ms]");
  for (std::size_t i = 0; i < result.frames.size(); ++i) {
    const rtslam::slam::FrameStats& f = result.frames[i];
    const double t_s = static_cast<double>(f.t - result.frames.front().t) * 1e-9;
    fmt::print("{:>5} {:>8.3f} {:>9} {:>7} {:>7} {:>4} {:>8.2f}\n", i, t_s, f.landmarks_in_map, f.matched,
               f.updated, f.initialized, f.time_total_ms);
  }

  // Trajectory length: the path of the estimated robot position p_WR.
  const auto& poses = result.estimate.poses;
  double length_m = 0.0;
  for (std::size_t i = 1; i < poses.size(); ++i) length_m += (poses[i].p_WR - poses[i - 1].p_WR).norm();
  fmt::print("trajectory: {} poses, {:.3f} m; landmarks: {} in the map, {} created\n", poses.size(), length_m,
             result.landmarks_final, result.landmarks_created);
  return poses.empty() ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const rtslam::Error& e) {  // ConfigError, IoError, ...: name the file, key or value
    std::cerr << "run_dataset: " << e.what() << '\n';
    return 1;
  } catch (const std::exception& e) {  // e.g. std::stoi on a bad --frames
    std::cerr << "run_dataset: " << e.what() << '\n';
    return 1;
  }
}
