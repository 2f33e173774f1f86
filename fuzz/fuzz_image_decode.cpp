// Fuzz target: the image decode path of every dataset reader — bytes -> decode_grey_image (cv::imdecode, grey,
// 8-bit) — and the reader's checks on the result: a decoded image is a non-empty 2-D CV_8UC1 matrix; an
// undecodable one is an empty Mat (never an exception, a crash or an unbounded allocation).
#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>

#include "fuzz_util.hpp"
#include "rtslam/io/codecs.hpp"
#include "rtslam/io/source.hpp"

using namespace rtslam;

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  fuzz::quiet_logs();
  // OpenCV's decoders (every format but 8-bit grey PNG) are in the codecs plugin: without it the target would fuzz
  // nothing but the plugin's IoError, so a missing plugin stops it here (IoError, uncaught).
  rtslam::io::codecs::load_plugin();
  cv::setNumThreads(1);  // one core: no decoder worker threads
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  cv::Mat img;
  fuzz::expect_typed_errors("decode_grey_image", "", [&] { img = io::decode_grey_image(data, size); });
  if (img.empty()) return 0;
  FUZZ_CHECK(img.dims == 2 && img.type() == CV_8UC1, "decoded image is not 2-D 8-bit grey");
  FUZZ_CHECK(img.rows > 0 && img.cols > 0, "decoded image has no pixels");
  // Touch every row as the front end would (reads through the Mat's own step).
  unsigned sum = 0;
  for (int r = 0; r < img.rows; ++r) sum += img.ptr<unsigned char>(r)[img.cols - 1];
  (void)sum;
  return 0;
}
