#pragma once
// Helpers of the CLI tests: temporary folders, JSON files, and the headless-Chromium screenshot check.
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include "rtslam/eval/process.hpp"
#include "support/temp_dir.hpp"

namespace rtslam::eval::test {

namespace fs = std::filesystem;

inline fs::path temp_dir(const std::string& name) { return ::rtslam::support::fresh_temp_dir("cli", name); }

inline nlohmann::json read_json(const fs::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in);
}

inline std::string chromium() {
  for (const char* name : {"chromium", "chromium-browser"}) {
    const std::string p = find_in_path(name);
    if (!p.empty()) return p;
  }
  return "";
}

// Screenshots `html` with headless Chromium and checks the picture shows plots (many non-white pixels, lines of
// several colours) rather than a blank or an error page.
inline void expect_screenshot_shows_figures(const fs::path& html, const fs::path& work) {
  const std::string browser = chromium();
  if (browser.empty()) GTEST_SKIP() << "chromium not installed (Debian package chromium)";
  const fs::path png = work / "screenshot.png";
  const fs::path profile = work / "chromium-profile";
  const int code = run_process({browser, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                                "--no-first-run", "--disable-background-networking", "--disable-component-update",
                                "--disable-sync", "--user-data-dir=" + profile.string(),
                                "--screenshot=" + png.string(), "--window-size=1200,2000",
                                "file://" + fs::absolute(html).string()},
                               (work / "chromium.log").string());
  ASSERT_EQ(code, 0) << "chromium failed, see " << (work / "chromium.log");
  ASSERT_TRUE(fs::exists(png));
  const cv::Mat img = cv::imread(png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.cols, 1200);
  cv::Mat grey;
  cv::Mat non_white;
  cv::extractChannel(img, grey, 1);
  cv::compare(grey, 240, non_white, cv::CmpTypes::CMP_LT);
  const double frac = cv::countNonZero(non_white) / static_cast<double>(img.total());
  EXPECT_GT(frac, 0.01) << "the screenshot is (almost) blank";
  // Coloured plot lines: pixels whose channels differ strongly (black text and grey grid do not).
  int coloured = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const cv::Vec3b p = img.at<cv::Vec3b>(y, x);
      const int mx = std::max({p[0], p[1], p[2]}), mn = std::min({p[0], p[1], p[2]});
      if (mx - mn > 80) ++coloured;
    }
  EXPECT_GT(coloured, 2000) << "no coloured plot lines in the screenshot";
}


}  // namespace rtslam::eval::test
