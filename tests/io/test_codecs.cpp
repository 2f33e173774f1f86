// The OpenCV codecs plugin (io/codecs.hpp): found in this build, forwards to OpenCV, and a missing or foreign plugin is
// an IoError naming every place tried.
#include <link.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>  // cv::IMREAD_*
#include <opencv2/videoio.hpp>    // cv::CAP_*

#include "rtslam/core/error.hpp"
#include "rtslam/io/codecs.hpp"
#include "support/temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
using namespace rtslam;

TEST(Codecs, LoadsThePluginOfThisBuildAndForwardsToOpenCV) {
  const std::string& path = io::codecs::load_plugin();
  EXPECT_TRUE(fs::is_regular_file(path)) << path;
  EXPECT_EQ(fs::path(path).filename(), "librtslam_opencv_codecs.so");

  // 8-bit and 16-bit grey images through PNG and back, pixel for pixel.
  cv::Mat grey(17, 23, CV_8UC1);
  cv::randu(grey, 0, 256);
  std::vector<unsigned char> png;
  ASSERT_TRUE(io::codecs::imencode(".png", grey, png));
  ASSERT_GT(png.size(), 8u);
  const cv::Mat back = io::codecs::imdecode(cv::Mat(1, static_cast<int>(png.size()), CV_8UC1, png.data()),
                                            cv::IMREAD_UNCHANGED);
  ASSERT_EQ(back.type(), CV_8UC1);
  EXPECT_EQ(cv::norm(back, grey, cv::NORM_INF), 0.0);
  cv::Mat deep(9, 11, CV_16UC1);
  cv::randu(deep, 0, 65536);
  const fs::path dir = support::fresh_temp_dir("test_io_codecs", "roundtrip");
  const std::string file = (dir / "deep.png").string();
  ASSERT_TRUE(io::codecs::imwrite(file, deep));
  const cv::Mat read = io::codecs::imread(file, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(read.type(), CV_16UC1);
  EXPECT_EQ(cv::norm(read, deep, cv::NORM_INF), 0.0);

  // OpenCV's own failures come back as OpenCV gives them: an empty image, no video.
  EXPECT_TRUE(io::codecs::imread((dir / "absent.png").string(), cv::IMREAD_UNCHANGED).empty());
  EXPECT_EQ(io::codecs::open_video((dir / "absent.avi").string(), cv::CAP_FFMPEG), nullptr);
  EXPECT_EQ(io::codecs::fourcc('M', 'J', 'P', 'G'), 0x47504A4D);
}

// A fresh process (gtest's threadsafe death test re-runs this test alone), since the plugin is looked for once.
// `plugin` names the file to try, `expected` the regular expression of the message.
void expect_load_error(const std::string& plugin, const std::string& expected) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        ::setenv("RTSLAM_CODECS_PLUGIN", plugin.c_str(), 1);
        try {
          io::codecs::load_plugin();
        } catch (const IoError& e) {
          std::fprintf(stderr, "%s\n", e.what());
          std::exit(3);
        }
        std::exit(0);
      },
      testing::ExitedWithCode(3), expected);
}

TEST(CodecsDeathTest, AMissingPluginIsAnIoErrorNamingThePathTried) {
  expect_load_error("/nonexistent/librtslam_opencv_codecs.so",
                    "tried /nonexistent/librtslam_opencv_codecs.so \\(no such file\\).*RTSLAM_CODECS_PLUGIN");
}

TEST(CodecsDeathTest, AFileThatIsNoPluginIsAnIoErrorSayingWhy) {
  const fs::path dir = support::fresh_temp_dir("test_io_codecs", "foreign");
  const fs::path fake = dir / "librtslam_opencv_codecs.so";
  std::ofstream(fake) << std::string(256, '#');  // longer than an ELF header
  // The death test's process runs this test again, with a folder of its own: the path's folder is not known here.
  expect_load_error(fake.string(),
                    "tried [^ ]*/librtslam_opencv_codecs.so \\([^)]*invalid ELF header\\).*RTSLAM_CODECS_PLUGIN");
}

TEST(CodecsDeathTest, ALibraryThatIsNoPluginIsAnIoErrorSayingSo) {
  // OpenCV's core library (loaded in this process: the path it was loaded from): a real shared object, without the
  // plugin's entry point.
  std::string core;
  dl_iterate_phdr(
      [](dl_phdr_info* info, std::size_t, void* data) {
        const std::string name = info->dlpi_name != nullptr ? info->dlpi_name : "";
        if (name.find("libopencv_core.so") == std::string::npos) return 0;
        *static_cast<std::string*>(data) = name;
        return 1;
      },
      &core);
  ASSERT_FALSE(core.empty()) << "libopencv_core is not loaded";
  expect_load_error(core, "\\(not an rtslam codecs plugin \\(no rtslam_opencv_codecs_api\\)\\)");
}

}  // namespace
