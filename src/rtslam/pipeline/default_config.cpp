#include "rtslam/pipeline/default_config.hpp"

#include <yaml-cpp/yaml.h>

namespace rtslam::pipeline {

ImageSlamOptions default_sim_options() {
  ImageSlamOptions o;
  apply_image_slam_config(YAML::Load(default_sim_config_yaml()), "built-in config/sim_mono.yaml", o);
  return o;
}

}  // namespace rtslam::pipeline
