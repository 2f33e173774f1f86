#pragma once
// OpenCV's image codecs and video I/O, loaded when first used (docs/install.md, "The OpenCV codecs plugin").
//
// Debian's libopencv-imgcodecs and libopencv-videoio pull in GDAL, GDCM, FFmpeg and GStreamer: 264 shared libraries,
// all bound at load time, ~150 ms at every start of a program that links them (`rtslam eval --help` took 190 ms,
// a test executable as long before its first line). rtslam's own libraries link OpenCV's core and imgproc only; the
// few calls into imgcodecs and videoio go through this header to a small plugin (librtslam_opencv_codecs.so, built
// and installed with rtslam) that is dlopen'ed on the first such call. The datasets' 8-bit grey PNGs (EuRoC, KITTI's
// grey sequences) are decoded by our own reader (png_grey.hpp) and never load it; colour or 16-bit images (TUM RGB-D),
// other formats, videos, cameras and writing images or videos do.
//
// Where the plugin is looked for, first found wins: the file named by RTSLAM_CODECS_PLUGIN (and only there when set);
// when this code is part of the executable, the installed layout relative to it (PREFIX/bin/rtslam ->
// PREFIX/lib/rtslam/); the build tree the library was compiled in; the installation prefix it was configured for. A
// candidate of another interface version or another build (rtslam version, OpenCV version, compiler) is skipped.
// When none loads, every call throws IoError naming the places tried and why each failed.
//
// The functions take and return what OpenCV's do (same flags, cv::IMREAD_* / cv::IMWRITE_* / cv::CAP_* constants
// from OpenCV's headers, which are enums and need no linking). cv::Exception from OpenCV passes through unchanged.
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace rtslam::io::codecs {

/// An open video file or capture device (cv::VideoCapture's calls that rtslam makes).
class VideoReader {
 public:
  virtual ~VideoReader() = default;
  virtual bool read(cv::Mat& frame) = 0;
  virtual bool grab() = 0;
  virtual bool retrieve(cv::Mat& frame) = 0;
  virtual double get(int property) const = 0;
  virtual bool set(int property, double value) = 0;
};

/// An open video file being written (cv::VideoWriter).
class VideoWriter {
 public:
  virtual ~VideoWriter() = default;
  virtual void write(const cv::Mat& frame) = 0;
  virtual void release() = 0;
};

/// cv::imread.
cv::Mat imread(const std::string& path, int flags);
/// cv::imwrite.
bool imwrite(const std::string& path, const cv::Mat& image, const std::vector<int>& params = {});
/// cv::imencode (extension with its dot, e.g. ".jpg").
bool imencode(const std::string& extension, const cv::Mat& image, std::vector<unsigned char>& out,
              const std::vector<int>& params = {});
/// cv::imdecode of the bytes in `buffer` (a 1 × N CV_8UC1 matrix).
cv::Mat imdecode(const cv::Mat& buffer, int flags);
/// A video file opened with OpenCV's backend `api` (cv::CAP_FFMPEG, cv::CAP_ANY, ...); nullptr when it cannot be.
std::unique_ptr<VideoReader> open_video(const std::string& path, int api);
/// Capture device N (/dev/videoN) through backend `api` (cv::CAP_V4L2); nullptr when it cannot be opened.
std::unique_ptr<VideoReader> open_camera(int index, int api);
/// A video file to write through backend `api` (cv::VideoWriter::open's arguments); nullptr when it does not take
/// the codec.
std::unique_ptr<VideoWriter> open_video_writer(const std::string& path, int api, int fourcc, double fps, cv::Size size,
                                               bool color);
/// cv::VideoWriter::fourcc (computed here: it needs no plugin).
constexpr int fourcc(char c1, char c2, char c3, char c4) {
  return (c1 & 255) + ((c2 & 255) << 8) + ((c3 & 255) << 16) + ((c4 & 255) << 24);
}

/// Loads the plugin now (the first call above does it otherwise); throws IoError when it cannot be found.
/// Returns the path it was loaded from.
const std::string& load_plugin();

/// The plugin's entry point: the table of functions above (plugin side). The interface version changes whenever
/// this table or the classes above do.
inline constexpr int kPluginInterface = 1;
struct PluginApi {
  int interface_version;
  const char* build;  // RTSLAM_CODECS_BUILD_ID of the plugin's build: rtslam, OpenCV and compiler versions
  cv::Mat (*imread)(const std::string&, int);
  bool (*imwrite)(const std::string&, const cv::Mat&, const std::vector<int>&);
  bool (*imencode)(const std::string&, const cv::Mat&, std::vector<unsigned char>&, const std::vector<int>&);
  cv::Mat (*imdecode)(const cv::Mat&, int);
  std::unique_ptr<VideoReader> (*open_video)(const std::string&, int);
  std::unique_ptr<VideoReader> (*open_camera)(int, int);
  std::unique_ptr<VideoWriter> (*open_video_writer)(const std::string&, int, int, double, cv::Size, bool);
};

}  // namespace rtslam::io::codecs

/// Exported by the plugin: its table (never null).
extern "C" const rtslam::io::codecs::PluginApi* rtslam_opencv_codecs_api();
