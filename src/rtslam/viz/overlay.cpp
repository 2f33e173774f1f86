#include "rtslam/viz/overlay.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <Eigen/Eigenvalues>
#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>  // cv::IMWRITE_*
#include <opencv2/videoio.hpp>    // cv::CAP_*
#include <opencv2/imgproc.hpp>

#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"

namespace rtslam::viz {

void OverlayOptions::validate() const {
  if (!(n_sigma > 0.0) || !std::isfinite(n_sigma)) {
    throw ConfigError(fmt::format("overlay: n_sigma = {} must be > 0", n_sigma));
  }
  if (!(search_tint >= 0.0 && search_tint <= 1.0)) {
    throw ConfigError(fmt::format("overlay: search_tint = {} must be in [0, 1]", search_tint));
  }
}

cv::Scalar match_colour(const FrameMatch& m) {
  if (m.ransac_inlier && m.updated) return colour::kInlier;
  if (m.updated) return colour::kUpdated;
  if (m.matched) return colour::kOutlier;
  if (m.searched) return colour::kFailed;
  return colour::kPredicted;
}

namespace {

// Fixed-point drawing (OpenCV's `shift`): sub-pixel centres and axes.
constexpr int kShift = 4;
constexpr double kOne = 1 << kShift;

cv::Point fixed(double x, double y) {
  return {static_cast<int>(std::lround(x * kOne)), static_cast<int>(std::lround(y * kOne))};
}

// The n_sigma ellipse of S at h: centre, semi-axes (major, minor) and the major axis angle in degrees. False when S
// is not a finite covariance.
bool ellipse_of(const Eigen::Vector2d& h, const Eigen::Matrix2d& S, double n_sigma, cv::Point& centre, cv::Size& axes,
                double& angle_deg) {
  if (!S.allFinite() || !h.allFinite()) return false;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(S);
  const Eigen::Vector2d sd = es.eigenvalues().cwiseMax(0.0).cwiseSqrt() * n_sigma;  // ascending
  if (!(sd[1] < 1e5)) return false;                                                   // absurd: skip
  const Eigen::Vector2d major = es.eigenvectors().col(1);
  angle_deg = std::atan2(major.y(), major.x()) * 180.0 / M_PI;
  centre = fixed(h.x(), h.y());
  axes = cv::Size(static_cast<int>(std::lround(sd[1] * kOne)), static_cast<int>(std::lround(sd[0] * kOne)));
  return true;
}

void cross(cv::Mat& img, const Eigen::Vector2d& p, double r, const cv::Scalar& c) {
  cv::line(img, fixed(p.x() - r, p.y()), fixed(p.x() + r, p.y()), c, 1, cv::LINE_AA, kShift);
  cv::line(img, fixed(p.x(), p.y() - r), fixed(p.x(), p.y() + r), c, 1, cv::LINE_AA, kShift);
}

}  // namespace

cv::Mat draw_overlay(const cv::Mat& grey, const FrameReport& report, const OverlayOptions& o) {
  cv::Mat img;
  if (grey.empty()) {
    img = cv::Mat::zeros(std::max(report.camera.height, 1), std::max(report.camera.width, 1), CV_8UC3);
  } else if (grey.channels() == 1) {
    cv::cvtColor(grey, img, cv::COLOR_GRAY2BGR);
  } else {
    img = grey.clone();
  }

  if (o.grid && !report.grid.empty()) {
    for (const GridCell& c : report.grid) {
      const cv::Point a = fixed(c.rect_px[0], c.rect_px[1]);
      const cv::Point b = fixed(c.rect_px[2] - 1.0, c.rect_px[3] - 1.0);
      if (c.occupied) {
        // Darken occupied cells a little: the empty ones are where new landmarks may start.
        cv::Rect r(cv::Point(static_cast<int>(c.rect_px[0]), static_cast<int>(c.rect_px[1])),
                   cv::Point(static_cast<int>(c.rect_px[2]), static_cast<int>(c.rect_px[3])));
        r &= cv::Rect(0, 0, img.cols, img.rows);
        if (r.area() > 0) img(r).convertTo(img(r), -1, 0.85, 0.0);
      }
      cv::rectangle(img, a, b, colour::kGrid, 1, cv::LINE_8, kShift);
    }
  }

  // Search regions: the ellipses of searched landmarks, filled on a copy blended back with a low opacity.
  if (o.search_regions && o.search_tint > 0.0) {
    cv::Mat tint = img.clone();
    bool any = false;
    for (const FrameMatch& m : report.matches) {
      if (!m.searched) continue;
      cv::Point c;
      cv::Size ax;
      double angle = 0.0;
      if (!ellipse_of(m.h, m.S, o.n_sigma, c, ax, angle)) continue;
      cv::ellipse(tint, c, ax, angle, 0, 360, match_colour(m), cv::FILLED, cv::LINE_AA, kShift);
      any = true;
    }
    if (any) cv::addWeighted(tint, o.search_tint, img, 1.0 - o.search_tint, 0.0, img);
  }

  for (const FrameMatch& m : report.matches) {
    cv::Point c;
    cv::Size ax;
    double angle = 0.0;
    if (!ellipse_of(m.h, m.S, o.n_sigma, c, ax, angle)) continue;
    const cv::Scalar col = match_colour(m);
    cv::ellipse(img, c, ax, angle, 0, 360, col, 1, cv::LINE_AA, kShift);
    cross(img, m.h, 2.0, col);
    if (m.matched && m.z.allFinite()) {
      if (o.innovations) cv::line(img, fixed(m.h.x(), m.h.y()), fixed(m.z.x(), m.z.y()), col, 1, cv::LINE_AA, kShift);
      cv::circle(img, fixed(m.z.x(), m.z.y()), static_cast<int>(3 * kOne), col, 1, cv::LINE_AA, kShift);
    }
    if (o.ids) {
      cv::putText(img, std::to_string(m.landmark_id),
                  cv::Point(static_cast<int>(m.h.x()) + 4, static_cast<int>(m.h.y()) - 4), cv::FONT_HERSHEY_PLAIN,
                  0.8, col, 1, cv::LINE_AA);
    }
  }

  if (o.new_landmarks) {
    for (const LandmarkReport& l : report.landmarks) {
      if (!l.created_now || !l.z0_px || !l.z0_px->allFinite()) continue;
      cv::circle(img, fixed(l.z0_px->x(), l.z0_px->y()), static_cast<int>(5 * kOne), colour::kNew, 1, cv::LINE_AA,
                 kShift);
      cross(img, *l.z0_px, 3.0, colour::kNew);
    }
  }

  if (o.hud) {
    const slam::FrameStats& s = report.stats;
    const std::string text =
        fmt::format("frame {}  t {:.3f} s  visible {}  matched {}  inliers {}  updated {}  new {}  map {}",
                    report.index, to_seconds(report.t), s.visible, s.matched, s.ransac_inliers, s.updated,
                    s.initialized, report.landmarks.size());
    const double scale = std::clamp(img.cols / 1500.0, 0.35, 0.8);
    int base = 0;
    const cv::Size ts = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, 1, &base);
    cv::rectangle(img, cv::Rect(0, 0, std::min(img.cols, ts.width + 8), ts.height + base + 6), cv::Scalar(0, 0, 0),
                  cv::FILLED);
    cv::putText(img, text, cv::Point(4, ts.height + 3), cv::FONT_HERSHEY_SIMPLEX, scale, colour::kText, 1,
                cv::LINE_AA);
  }
  return img;
}

// ---------------------------------------------------------------------------------------------------------------

OverlayWriter::OverlayWriter(std::string dir, OverlayOptions options) : dir_(std::move(dir)), options_(options) {
  options_.validate();
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  if (ec || !std::filesystem::is_directory(dir_)) {
    throw IoError(fmt::format("{}: cannot create the overlay folder ({})", dir_, ec ? ec.message() : "not a folder"));
  }
  index_path_ = (std::filesystem::path(dir_) / "index.csv").string();
  index_.open(index_path_, std::ios::out | std::ios::trunc);
  if (!index_) throw IoError(fmt::format("{}: cannot write", index_path_));
  index_ << "frame,t_ns,file,visible,searched,matched,ransac_inliers,updated,initialized,nis_sum,nis_count\n";
  io::codecs::load_plugin();  // the PNG encoder: loaded now (~150 ms), not on the filter thread at the first frame
}

OverlayWriter::~OverlayWriter() {
  try {
    close();
  } catch (...) {  // destructors never throw; close() explicitly to see errors
  }
}

std::string OverlayWriter::file_name(int index, TimeNs t) { return fmt::format("frame_{:06d}_{:019d}.png", index, t); }

void OverlayWriter::write(const FrameReport& r) {
  const std::string name = file_name(r.index, r.t);
  const std::string path = (std::filesystem::path(dir_) / name).string();
  const cv::Mat img = draw_overlay(r, options_);
  bool ok = false;
  try {
    ok = io::codecs::imwrite(path, img, {cv::IMWRITE_PNG_COMPRESSION, 1});
  } catch (const cv::Exception& e) {
    throw IoError(fmt::format("{}: cannot write the overlay image ({})", path, e.what()));
  }
  if (!ok) throw IoError(fmt::format("{}: cannot write the overlay image", path));
  const Nis nis = frame_nis(r.matches);
  const slam::FrameStats& s = r.stats;
  index_ << fmt::format("{},{},{},{},{},{},{},{},{},{},{}\n", r.index, r.t, name, s.visible, s.searched, s.matched,
                        s.ransac_inliers, s.updated, s.initialized, nis.sum, nis.count);
  if (!index_) throw IoError(fmt::format("{}: cannot write", index_path_));
  ++written_;
}

void OverlayWriter::close() {
  if (!index_.is_open()) return;
  index_.close();
  if (index_.fail()) throw IoError(fmt::format("{}: cannot write", index_path_));
}

// ---------------------------------------------------------------------------------------------------------------

std::vector<std::string> VideoWriter::fourccs_for(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".avi" || ext == ".mkv") return {"MJPG"};
  if (ext == ".mp4" || ext == ".m4v" || ext == ".mov") return {"avc1", "mp4v"};
  if (ext == ".webm") return {"VP80"};
  throw IoError(fmt::format("{}: unknown video extension '{}' (use .avi, .mkv, .mp4, .m4v, .mov or .webm)", path, ext));
}

VideoWriter::VideoWriter(std::string path, double fps, OverlayOptions options)
    : path_(std::move(path)), fps_(fps), options_(options) {
  options_.validate();
  if (!(fps_ >= 0.0) || !std::isfinite(fps_)) throw ConfigError(fmt::format("video: fps = {} must be >= 0", fps_));
  (void)fourccs_for(path_);  // an unknown extension fails now, not at the second frame
  io::codecs::load_plugin();  // and so does a missing codecs plugin (its loading, ~150 ms, is not a frame's time)
  const auto parent = std::filesystem::path(path_).parent_path();
  if (!parent.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(parent, ec);
  }
}

VideoWriter::~VideoWriter() {
  try {
    close();
  } catch (...) {  // destructors never throw; close() explicitly to see errors
  }
}

void VideoWriter::open(double fps, cv::Size size) {
  size_ = size;
  std::string tried;
  for (const std::string& cc : fourccs_for(path_)) {
    const int code = io::codecs::fourcc(cc[0], cc[1], cc[2], cc[3]);
    bool ok = false;
    try {
      writer_ = io::codecs::open_video_writer(path_, cv::CAP_ANY, code, fps, size, true);
      ok = writer_ != nullptr;
    } catch (const cv::Exception&) {
      ok = false;
    }
    if (ok) {
      logger("viz")->debug("video {}: {} at {:.2f} fps, {}x{}", path_, cc, fps, size.width, size.height);
      return;
    }
    tried += (tried.empty() ? "" : ", ") + cc;
  }
  writer_.reset();
  throw IoError(fmt::format("{}: OpenCV cannot write this video (codecs tried: {}; its videoio needs the FFmpeg "
                            "backend, Debian package libopencv-videoio-dev)",
                            path_, tried));
}

void VideoWriter::write(const FrameReport& r) {
  cv::Mat img = draw_overlay(r, options_);
  if (!writer_) {
    if (pending_.empty() && fps_ <= 0.0) {
      pending_ = std::move(img);
      pending_t_ = r.t;
      return;
    }
    double fps = fps_;
    if (fps <= 0.0) {
      const double dt = to_seconds(r.t - pending_t_);
      fps = dt > 0.0 ? std::clamp(1.0 / dt, 1.0, 1000.0) : 20.0;
    }
    const cv::Size size = pending_.empty() ? img.size() : pending_.size();
    open(fps, size);
    if (!pending_.empty()) {
      writer_->write(pending_);
      ++written_;
      pending_.release();
    }
  }
  if (img.size() != size_) cv::resize(img, img, size_);  // a video has one size
  writer_->write(img);
  ++written_;
}

void VideoWriter::close() {
  if (!writer_ && !pending_.empty()) open(fps_ > 0.0 ? fps_ : 20.0, pending_.size());
  if (writer_ && !pending_.empty()) {
    writer_->write(pending_);
    ++written_;
    pending_.release();
  }
  if (writer_) {
    writer_->release();
    writer_.reset();
  }
}

}  // namespace rtslam::viz
