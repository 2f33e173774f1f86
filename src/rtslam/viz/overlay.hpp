#pragma once
// The per-frame overlay of the paper's 2D display, drawn by ONE routine (draw_overlay) for the live viewer, the
// PNG-per-frame writer (`rtslam run --overlays DIR`) and the video writer (`rtslam run --video FILE`).
//
// Wiring (on the filter thread, or on any thread that owns the writer):
//   viz::OverlayWriter overlays(dir);            // creates dir; throws IoError if it cannot
//   viz::VideoWriter video(file);                // codec from the extension; throws IoError if unavailable
//   ... per processed image: overlays.write(report); video.write(report);
//   overlays.close(); video.close();             // also done by the destructors (which never throw)
//
// What is drawn (BGR colours below; docs/viewer.md has the legend):
//   - every visible landmark's predicted observation h with its n_sigma (3σ) innovation ellipse from S (the first
//     prediction of the frame), coloured by its fate: grey = predicted, not searched (budget); blue = searched,
//     not found; red = found but rejected (outside the RANSAC support and gated out: an outlier); yellow = RANSAC
//     inlier (corrected in the batched update); green = corrected by the gated active search;
//   - the search region of every searched landmark: its 3σ ellipse filled with a light tint (active search scans
//     the positions inside it; later stages search the smaller ellipse of the re-prediction);
//   - the measured pixel z of every match (circle) and the innovation z − h (a segment);
//   - new landmarks (magenta: a circle and a cross at the pixel they were initialized at);
//   - the randomly moving init grid when the report has it (thin cyan lines; occupied cells darkened);
//   - a text line: frame, time, visible / matched / inliers / updated / new.
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "rtslam/io/codecs.hpp"
#include "rtslam/viz/report.hpp"

namespace rtslam::viz {

/// Colours (BGR) of the overlay: also the viewer's legend.
namespace colour {
inline const cv::Scalar kPredicted{160, 160, 160};  // visible, not searched
inline const cv::Scalar kFailed{255, 128, 0};       // searched, not found
inline const cv::Scalar kOutlier{0, 0, 255};        // found, rejected
inline const cv::Scalar kInlier{0, 255, 255};       // RANSAC inlier
inline const cv::Scalar kUpdated{0, 255, 0};        // gated active-search update
inline const cv::Scalar kNew{255, 0, 255};          // initialized in this frame
inline const cv::Scalar kGrid{160, 160, 0};         // init grid
inline const cv::Scalar kText{255, 255, 255};
}  // namespace colour

struct OverlayOptions {
  double n_sigma = 3.0;         // ellipse size (the search uses search/n_sigma: pass the same)
  bool search_regions = true;   // tint the ellipses of searched landmarks
  bool innovations = true;      // segment h → z of matches
  bool new_landmarks = true;
  bool grid = true;             // when the report has the grid
  bool ids = false;             // landmark ids next to h
  bool hud = true;              // the text line
  double search_tint = 0.18;    // opacity of the search-region tint, in [0, 1]
  void validate() const;        // throws ConfigError naming the option
};

/// The colour of a match's ellipse (see above).
cv::Scalar match_colour(const FrameMatch& m);

/// Draws the report on `grey` (CV_8UC1, or CV_8UC3 taken as BGR): returns a new CV_8UC3 BGR image of the same size.
/// An empty `grey` gives a black image of the camera's size. Never throws for a valid report.
cv::Mat draw_overlay(const cv::Mat& grey, const FrameReport& report, const OverlayOptions& options = {});
/// Same, on the report's own image.
inline cv::Mat draw_overlay(const FrameReport& report, const OverlayOptions& options = {}) {
  return draw_overlay(report.image, report, options);
}

/// `--overlays DIR`: one PNG per processed frame, named `frame_IIIIII_TTTTTTTTTTTTTTTTTTT.png` (index, then the time
/// in ns, both zero-padded so that names sort in time order), and DIR/index.csv with one row per PNG
/// (`frame,t_ns,file,visible,searched,matched,ransac_inliers,updated,initialized,nis_sum,nis_count`) that
/// `rtslam view` reads.
class OverlayWriter {
 public:
  explicit OverlayWriter(std::string dir, OverlayOptions options = {});
  ~OverlayWriter();
  OverlayWriter(const OverlayWriter&) = delete;
  OverlayWriter& operator=(const OverlayWriter&) = delete;
  /// Draws and writes one frame; throws IoError naming the file when it cannot write.
  void write(const FrameReport& report);
  void close();
  const std::string& dir() const { return dir_; }
  int frames_written() const { return written_; }
  static std::string file_name(int index, TimeNs t);

 private:
  std::string dir_;
  OverlayOptions options_;
  std::string index_path_;
  std::ofstream index_;
  int written_ = 0;
};

/// `--video FILE`: the overlays as a video through cv::VideoWriter. The codec comes from the extension: .avi →
/// MJPG, .mp4/.m4v/.mov → H.264 (avc1; MPEG-4 part 2, mp4v, when OpenCV's FFmpeg has no H.264 encoder), .mkv →
/// MJPG in Matroska, .webm → VP8. The writer opens at the second frame with
/// the rate of the first two frames' times (or `fps` when > 0) and the first frame's size. Throws IoError naming
/// the file when the extension is unknown or OpenCV has no backend for the codec.
class VideoWriter {
 public:
  explicit VideoWriter(std::string path, double fps = 0.0, OverlayOptions options = {});
  ~VideoWriter();
  VideoWriter(const VideoWriter&) = delete;
  VideoWriter& operator=(const VideoWriter&) = delete;
  void write(const FrameReport& report);
  void close();
  int frames_written() const { return written_; }
  /// The FOURCCs to try for a file name, e.g. {"MJPG"}; throws IoError for an unknown extension.
  static std::vector<std::string> fourccs_for(const std::string& path);

 private:
  void open(double fps, cv::Size size);
  std::string path_;
  double fps_;
  OverlayOptions options_;
  std::unique_ptr<io::codecs::VideoWriter> writer_;
  cv::Size size_;
  cv::Mat pending_;       // first frame, until the rate is known
  TimeNs pending_t_ = 0;
  int written_ = 0;
};

}  // namespace rtslam::viz
