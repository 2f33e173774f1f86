// Writes small seed images for fuzz_image_decode: for each input image (or, with --synthetic, a gradient), a 32x24
// grey crop, a 64x48 resize and colour and 16-bit variants in every format the dataset readers meet (PNG, PGM/PPM,
// JPEG, BMP, TIFF). Used by scripts/fuzz.sh on ../shared/datasets images; the committed fuzz/corpus/image_decode/
// seeds were written with --synthetic.
//   fuzz_make_image_seeds OUT_DIR IMAGE...
//   fuzz_make_image_seeds OUT_DIR --synthetic
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace {

void write_variants(const std::string& out, const std::string& stem, const cv::Mat& grey) {
  const cv::Mat crop = grey(cv::Rect((grey.cols - 32) / 2, (grey.rows - 24) / 2, 32, 24)).clone();
  cv::Mat small;
  cv::resize(grey, small, cv::Size(64, 48), 0, 0, cv::INTER_AREA);
  cv::Mat colour;
  cv::cvtColor(crop, colour, cv::COLOR_GRAY2BGR);
  colour.col(0).setTo(cv::Scalar(0, 0, 255));
  cv::Mat deep;
  crop.convertTo(deep, CV_16U, 257.0);
  const std::vector<std::pair<std::string, cv::Mat>> files = {
      {"crop.png", crop},     {"crop.pgm", crop},     {"crop.jpg", crop},      {"crop.bmp", crop},
      {"crop.tiff", crop},    {"small.png", small},   {"colour.png", colour},  {"colour.ppm", colour},
      {"colour.jpg", colour}, {"colour.bmp", colour}, {"deep16.png", deep},    {"deep16.tiff", deep},
  };
  for (const auto& [name, img] : files) {
    const std::string path = out + "/" + stem + "-" + name;
    if (!cv::imwrite(path, img)) std::fprintf(stderr, "cannot write %s\n", path.c_str());
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s OUT_DIR (IMAGE... | --synthetic)\n", argv[0]);
    return 2;
  }
  const std::string out = argv[1];
  std::filesystem::create_directories(out);
  if (std::string(argv[2]) == "--synthetic") {
    cv::Mat g(48, 64, CV_8UC1);
    for (int r = 0; r < g.rows; ++r)
      for (int c = 0; c < g.cols; ++c) g.at<unsigned char>(r, c) = static_cast<unsigned char>((r * 5 + c * 3) & 0xff);
    write_variants(out, "synthetic", g);
    return 0;
  }
  for (int i = 2; i < argc; ++i) {
    const cv::Mat g = cv::imread(argv[i], cv::IMREAD_GRAYSCALE);
    if (g.empty() || g.cols < 64 || g.rows < 48) {
      std::fprintf(stderr, "skipping %s (not an image of at least 64x48)\n", argv[i]);
      continue;
    }
    write_variants(out, std::filesystem::path(argv[i]).stem().string(), g);
  }
  return 0;
}
