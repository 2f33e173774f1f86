#include "rtslam/pipeline/demo_config.hpp"

#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"

namespace rtslam::pipeline {
namespace {

TEST(DemoConfig, RoundTripsThroughYaml) {
  PointDemoOptions o;
  o.seed = 17;
  o.association.max_updates = 12;
  o.map.policy = strategies::MapPolicyOptions::Policy::VisualOdometry;
  PointDemoOptions back;
  apply_demo_config(to_yaml(o), "test", back);
  EXPECT_EQ(back.seed, 17u);
  EXPECT_EQ(back.association.max_updates, 12);
  EXPECT_EQ(back.map.policy, strategies::MapPolicyOptions::Policy::VisualOdometry);
  EXPECT_EQ(YAML::Dump(to_yaml(back)), YAML::Dump(to_yaml(o)));
}

TEST(DemoConfig, UnknownKeyIsAnErrorNamingIt) {
  PointDemoOptions o;
  try {
    apply_demo_config(YAML::Load("association:\n  max_update: 3\n"), "my.yaml", o);
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("my.yaml"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("max_update"), std::string::npos);
  }
}

TEST(DemoConfig, OutOfBoundValueIsAnError) {
  PointDemoOptions o;
  EXPECT_THROW(apply_demo_config(YAML::Load("demo:\n  duration_s: -1\n"), "x.yaml", o), ConfigError);
  EXPECT_THROW(apply_demo_config(YAML::Load("map_manager:\n  policy: sometimes\n"), "x.yaml", o), ConfigError);
  EXPECT_THROW(apply_demo_config(YAML::Load("demo:\n  n_points: many\n"), "x.yaml", o), ConfigError);
}

TEST(DemoConfig, MissingFileIsAnIoError) { EXPECT_THROW(load_demo_config("/nonexistent/rtslam.yaml"), IoError); }

}  // namespace
}  // namespace rtslam::pipeline
