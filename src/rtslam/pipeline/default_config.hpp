#pragma once
// The built-in configuration of `rtslam run` on the simulator (no --config, no dataset or sim:PRESET): the text of
// config/sim_mono.yaml, embedded at build time so that the file and the default run cannot drift apart. Runs on a
// dataset without --config use the options' own defaults (RT-SLAM's values).
#include "rtslam/pipeline/image_slam.hpp"

namespace rtslam::pipeline {

/// config/sim_mono.yaml as it was when the binary was built.
const char* default_sim_config_yaml();

/// ImageSlamOptions read from default_sim_config_yaml().
ImageSlamOptions default_sim_options();

}  // namespace rtslam::pipeline
