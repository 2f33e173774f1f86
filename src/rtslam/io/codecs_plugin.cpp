// librtslam_opencv_codecs.so: the OpenCV imgcodecs and videoio calls of rtslam, loaded on first use (codecs.hpp).
#include <memory>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "rtslam/io/codecs.hpp"

namespace rtslam::io::codecs {
namespace {

class CaptureReader final : public VideoReader {
 public:
  explicit CaptureReader(std::unique_ptr<cv::VideoCapture> capture) : capture_(std::move(capture)) {}
  bool read(cv::Mat& frame) override { return capture_->read(frame); }
  bool grab() override { return capture_->grab(); }
  bool retrieve(cv::Mat& frame) override { return capture_->retrieve(frame); }
  double get(int property) const override { return capture_->get(property); }
  bool set(int property, double value) override { return capture_->set(property, value); }

 private:
  std::unique_ptr<cv::VideoCapture> capture_;
};

class FileWriter final : public VideoWriter {
 public:
  explicit FileWriter(std::unique_ptr<cv::VideoWriter> writer) : writer_(std::move(writer)) {}
  void write(const cv::Mat& frame) override { writer_->write(frame); }
  void release() override { writer_->release(); }

 private:
  std::unique_ptr<cv::VideoWriter> writer_;
};

std::unique_ptr<VideoReader> reader_or_null(std::unique_ptr<cv::VideoCapture> capture) {
  if (!capture->isOpened()) return nullptr;
  return std::make_unique<CaptureReader>(std::move(capture));
}

const PluginApi kApi{
    kPluginInterface,
    RTSLAM_CODECS_BUILD_ID,
    [](const std::string& path, int flags) { return cv::imread(path, flags); },
    [](const std::string& path, const cv::Mat& image, const std::vector<int>& params) {
      return cv::imwrite(path, image, params);
    },
    [](const std::string& ext, const cv::Mat& image, std::vector<unsigned char>& out, const std::vector<int>& params) {
      return cv::imencode(ext, image, out, params);
    },
    [](const cv::Mat& buffer, int flags) { return cv::imdecode(buffer, flags); },
    [](const std::string& path, int api) { return reader_or_null(std::make_unique<cv::VideoCapture>(path, api)); },
    [](int index, int api) { return reader_or_null(std::make_unique<cv::VideoCapture>(index, api)); },
    [](const std::string& path, int api, int fourcc, double fps, cv::Size size,
       bool color) -> std::unique_ptr<VideoWriter> {
      auto writer = std::make_unique<cv::VideoWriter>();
      if (!writer->open(path, api, fourcc, fps, size, color)) return nullptr;
      return std::make_unique<FileWriter>(std::move(writer));
    },
};

}  // namespace
}  // namespace rtslam::io::codecs

extern "C" __attribute__((visibility("default"))) const rtslam::io::codecs::PluginApi* rtslam_opencv_codecs_api() {
  return &rtslam::io::codecs::kApi;
}
