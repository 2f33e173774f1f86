#include "rtslam/calib/check.hpp"


#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <deque>
#include <exception>
#include <mutex>
#include <thread>
#include <variant>

#include <fmt/format.h>

#include "rtslam/calib/estimators.hpp"
#include "rtslam/core/error.hpp"
#include "rtslam/core/log.hpp"
#include "rtslam/io/prefetch.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/models/sensors/pinhole_camera.hpp"
#include "rtslam/sim/simulation.hpp"
#include "rtslam/vision/harris.hpp"
#include "rtslam/vision/zncc.hpp"

namespace rtslam::calib {

using Eigen::Matrix3d;
using Eigen::Vector2d;
using Eigen::Vector3d;

void CheckOptions::validate() const {
  const std::string w = "imu/calibration_check";
  require_bound(duration_s > 0.5 && duration_s <= 120.0, w, "duration", duration_s, "in (0.5, 120] s");
  require_bound(max_wait_s >= 0.0 && max_wait_s <= 3600.0, w, "max_wait", max_wait_s, "in [0, 3600] s");
  require_bound(onset_rate >= 0.0 && onset_rate <= 10.0, w, "onset_rate", onset_rate, "in [0, 10] rad/s");
  require_bound(max_rotation_deg > 0.0 && max_rotation_deg <= 180.0, w, "max_rotation_deg", max_rotation_deg,
                "in (0, 180] deg");
  require_bound(max_offset_ms > 0.0 && max_offset_ms <= 1000.0, w, "max_offset_ms", max_offset_ms, "in (0, 1000] ms");
  require_bound(offset_range_ms >= 10.0 && offset_range_ms <= 1000.0, w, "offset_range_ms", offset_range_ms,
                "in [10, 1000] ms");
  require_bound(min_excitation >= 0.0 && min_excitation <= 10.0, w, "min_excitation", min_excitation,
                "in [0, 10] rad/s");
  require_bound(min_correlation >= 0.0 && min_correlation <= 1.0, w, "min_correlation", min_correlation, "in [0, 1]");
  require_bound(threads >= 0 && threads <= 256, w, "threads", threads, "in [0, 256] (0: one per core, at most 4)");
  require_bound(cells_x >= 2 && cells_x <= 64, w, "cells_x", cells_x, "in [2, 64]");
  require_bound(cells_y >= 2 && cells_y <= 64, w, "cells_y", cells_y, "in [2, 64]");
  require_bound(patch_size >= 5 && patch_size <= 31 && patch_size % 2 == 1, w, "patch_size", patch_size,
                "odd, in [5, 31]");
  require_bound(min_score >= 0.0 && min_score <= 1.0, w, "min_score", min_score, "in [0, 1]");
  require_bound(search_px >= 2.0 && search_px <= 200.0, w, "search_px", search_px, "in [2, 200] px");
  require_bound(gap_factor > 1.0 && gap_factor <= 100.0, w, "gap_factor", gap_factor, "in (1, 100]");
}

CheckOptions CheckOptions::from_yaml(YamlMap& m) {
  CheckOptions o;
  m.get("enabled", o.enabled);
  m.get("duration", o.duration_s);
  m.get("max_wait", o.max_wait_s);
  m.get("onset_rate", o.onset_rate);
  m.get("max_rotation_deg", o.max_rotation_deg);
  m.get("max_offset_ms", o.max_offset_ms);
  m.get("offset_range_ms", o.offset_range_ms);
  m.get("min_excitation", o.min_excitation);
  m.get("min_correlation", o.min_correlation);
  m.get("cells_x", o.cells_x);
  m.get("cells_y", o.cells_y);
  m.get("patch_size", o.patch_size);
  m.get("min_score", o.min_score);
  m.get("search_px", o.search_px);
  m.get("gap_factor", o.gap_factor);
  m.get("epipolar", o.epipolar);
  m.finish();
  o.validate();
  return o;
}

YAML::Node CheckOptions::to_yaml() const {
  YAML::Node n;
  n["enabled"] = enabled;
  n["duration"] = duration_s;
  n["max_wait"] = max_wait_s;
  n["onset_rate"] = onset_rate;
  n["max_rotation_deg"] = max_rotation_deg;
  n["max_offset_ms"] = max_offset_ms;
  n["offset_range_ms"] = offset_range_ms;
  n["min_excitation"] = min_excitation;
  n["min_correlation"] = min_correlation;
  n["cells_x"] = cells_x;
  n["cells_y"] = cells_y;
  n["patch_size"] = patch_size;
  n["min_score"] = min_score;
  n["search_px"] = search_px;
  n["gap_factor"] = gap_factor;
  n["epipolar"] = epipolar;
  return n;
}

std::string to_string(Verdict v) {
  switch (v) {
    case Verdict::ok: return "ok";
    case Verdict::warning: return "warning";
    case Verdict::not_enough_motion: return "not_enough_motion";
    case Verdict::failed: return "failed";
  }
  return "failed";
}

namespace {

double rad2deg(double r) { return r * 180.0 / M_PI; }

double angle_between_deg(const Matrix3d& A, const Matrix3d& B) {
  return rad2deg(math::log_so3(Eigen::Quaterniond(A.transpose() * B)).norm());
}

vision::ImageView view_of(const cv::Mat& m) {
  return vision::ImageView{m.data, m.cols, m.rows, static_cast<int>(m.step[0])};
}

struct Frame {
  TimeNs t = 0;
  cv::Mat image;
};

// Harris corners on a grid, tracked image to image by ZNCC around a constant-image-velocity prediction (no gyro).
// Returns, per interval (i, i + 1), the matched pixel pairs.
std::vector<std::vector<std::pair<Vector2d, Vector2d>>> track(const std::vector<Frame>& frames,
                                                              const models::CameraIntrinsics& in,
                                                              const CheckOptions& o) {
  struct Track {
    Vector2d px, vel = Vector2d::Zero();
    vision::Patch patch;
    int cell = 0;
  };
  vision::HarrisDetector harris;
  vision::ZnccOptions zo;
  zo.patch_size = o.patch_size;
  zo.threshold = o.min_score;
  vision::ZnccMatcher matcher(zo);
  const int half = o.patch_size / 2;
  const int border = half + 2;
  const int ncells = o.cells_x * o.cells_y;
  std::vector<Track> tracks;
  std::vector<std::vector<std::pair<Vector2d, Vector2d>>> pairs(frames.empty() ? 0 : frames.size() - 1);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const vision::ImageView view = view_of(frames[i].image);
    if (view.width != in.width || view.height != in.height) {
      tracks.clear();
      continue;
    }
    if (i > 0) {
      std::vector<Track> alive;
      for (Track& t : tracks) {
        const Vector2d pred = t.px + t.vel;
        if (pred.x() < border || pred.y() < border || pred.x() > in.width - 1 - border ||
            pred.y() > in.height - 1 - border) {
          continue;
        }
        const vision::MatchResult m = matcher.match(t.patch, view, vision::SearchEllipse::box(pred, o.search_px,
                                                                                              o.search_px));
        if (!m.found) continue;
        const Vector2d p(m.u, m.v);
        pairs[i - 1].emplace_back(t.px, p);
        if (!t.patch.extract(view, m.u_px, m.v_px, o.patch_size) || t.patch.centred_energy() <= 0) continue;
        t.vel = p - t.px;
        t.px = p;
        const int cx = std::clamp(static_cast<int>((p.x() - border) * o.cells_x / (in.width - 2 * border)), 0,
                                  o.cells_x - 1);
        const int cy = std::clamp(static_cast<int>((p.y() - border) * o.cells_y / (in.height - 2 * border)), 0,
                                  o.cells_y - 1);
        t.cell = cy * o.cells_x + cx;
        alive.push_back(std::move(t));
      }
      tracks = std::move(alive);
    }
    // New corners in the cells without a track.
    std::vector<char> occupied(static_cast<std::size_t>(ncells), 0);
    for (const Track& t : tracks) occupied[static_cast<std::size_t>(t.cell)] = 1;
    for (int cy = 0; cy < o.cells_y; ++cy) {
      for (int cx = 0; cx < o.cells_x; ++cx) {
        const int cell = cy * o.cells_x + cx;
        if (occupied[static_cast<std::size_t>(cell)]) continue;
        const auto c =
            harris.best_corner(view, vision::grid_cell(in.width, in.height, border, o.cells_x, o.cells_y, cx, cy));
        if (!c) continue;
        Track t;
        if (!t.patch.extract(view, c->u_px, c->v_px, o.patch_size) || t.patch.centred_energy() <= 0) continue;
        t.px = Vector2d(c->u_px, c->v_px);
        t.cell = cell;
        tracks.push_back(std::move(t));
      }
    }
  }
  return pairs;
}

// Motion onset: the gyro's mean over the last 0.1 s leaves the mean of the first 0.5 s by more than onset_rate.
class OnsetDetector {
 public:
  explicit OnsetDetector(double rate) : rate_(rate) {}
  bool add(const io::ImuSample& s) {
    if (fired_) return true;
    if (!t0_) t0_ = s.t;
    if (s.t - *t0_ <= 500'000'000) {
      ref_ += s.gyro;
      ++n_ref_;
    }
    recent_.push_back(s);
    while (!recent_.empty() && s.t - recent_.front().t > 100'000'000) recent_.pop_front();
    if (n_ref_ == 0 || recent_.size() < 3) return false;
    Vector3d m = Vector3d::Zero();
    for (const auto& r : recent_) m += r.gyro;
    m /= static_cast<double>(recent_.size());
    fired_ = (m - ref_ / n_ref_).norm() > rate_;
    return fired_;
  }

 private:
  double rate_;
  std::optional<TimeNs> t0_;
  Vector3d ref_ = Vector3d::Zero();
  int n_ref_ = 0;
  std::deque<io::ImuSample> recent_;
  bool fired_ = false;
};

}  // namespace

std::vector<std::string> CheckResult::lines() const {
  std::vector<std::string> out;
  out.push_back(fmt::format("calibration check: {}{}", to_string(verdict), reason.empty() ? "" : " (" + reason + ")"));
  out.push_back(fmt::format("  window {:.1f}–{:.1f} s: {} images, {}/{} intervals with a camera rotation ({:.0f} "
                            "tracked features, epipolar RMS {:.2f} px)",
                            window_start_s, window_end_s, images, intervals_valid, intervals, median_features,
                            visual_rms_px));
  if (rotation_measured) {
    out.push_back(fmt::format("  camera–IMU rotation: measured {:.2f} deg from the configured T_RS (± {:.2f} deg; "
                              "{:.2f} deg from its inverse; excitation {:.2f} rad/s, rate residual {:.3f} rad/s)",
                              rotation_error_deg, rotation_std_deg, rotation_to_inverse_deg, excitation_rad_s,
                              rate_rms_rad_s));
  } else {
    out.push_back(fmt::format("  camera–IMU rotation: not measured (excitation {:.2f} rad/s, std {:.1f} deg)",
                              excitation_rad_s, rotation_std_deg));
  }
  if (offset_measured) {
    out.push_back(fmt::format("  time offset t_d (t_imu = t_cam + t_d): measured {:.1f} ms, configured {:.1f} ms "
                              "(rate correlation {:.2f}, next peak {:.2f})",
                              t_d_measured_ms, t_d_configured_ms, correlation, second_peak_correlation));
  } else {
    out.push_back(fmt::format("  time offset t_d: not measured (rate correlation {:.2f}, next peak {:.2f}), configured "
                              "{:.1f} ms", correlation, second_peak_correlation, t_d_configured_ms));
  }
  out.push_back("  input: " + stream.line());
  for (const auto& w : warnings) out.push_back("  WARNING: " + w);
  return out;
}

nlohmann::json CheckResult::to_json() const {
  const auto mat = [](const Matrix3d& R) {
    const Eigen::Quaterniond q(R);
    return std::vector<double>{q.w(), q.x(), q.y(), q.z()};
  };
  nlohmann::json j;
  j["verdict"] = to_string(verdict);
  j["reason"] = reason;
  j["warnings"] = warnings;
  j["window_s"] = {window_start_s, window_end_s};
  j["images"] = images;
  j["intervals"] = intervals;
  j["intervals_with_rotation"] = intervals_valid;
  j["median_features"] = median_features;
  j["visual_rms_px"] = visual_rms_px;
  j["rotation"] = {{"measured", rotation_measured},
                   {"q_RS_measured_wxyz", mat(R_RS_measured)},
                   {"q_RS_configured_wxyz", mat(R_RS_configured)},
                   {"error_deg", rotation_error_deg},
                   {"to_inverse_deg", rotation_to_inverse_deg},
                   {"looks_inverted", looks_inverted},
                   {"std_deg", rotation_std_deg},
                   {"excitation_rad_s", excitation_rad_s},
                   {"rate_rms_rad_s", rate_rms_rad_s},
                   {"gyro_bias", {gyro_bias.x(), gyro_bias.y(), gyro_bias.z()}}};
  j["time_offset"] = {{"measured", offset_measured},
                      {"t_d_measured_ms", t_d_measured_ms},
                      {"t_d_configured_ms", t_d_configured_ms},
                      {"error_ms", offset_error_ms},
                      {"correlation", correlation},
                      {"second_peak_correlation", second_peak_correlation}};
  j["stream"] = stream.to_json();
  j["cost_ms"] = cost_ms;
  return j;
}

CheckResult check_calibration(io::Source& source, const io::Rig& rig, int camera, TimeNs t_d_configured,
                              const CheckOptions& o) {
  const auto clock0 = std::chrono::steady_clock::now();
  CheckResult res;
  res.t_d_configured_ms = to_seconds(t_d_configured) * 1e3;
  const auto finish = [&](Verdict v, std::string reason) {
    res.verdict = v;
    if (!reason.empty()) res.reason = std::move(reason);
    res.cost_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - clock0).count();
    return res;
  };
  if (camera < 0 || camera >= static_cast<int>(rig.cameras.size())) {
    return finish(Verdict::failed, fmt::format("the rig has no camera {}", camera));
  }
  const io::CameraCalibration& cal = rig.cameras[static_cast<std::size_t>(camera)];
  res.R_RS_configured = cal.T_RS.rotation();
  // An IMU mounted off R (ImuCalibration::T_RS): the gyro measures in the IMU frame I, rates rotate by R_RI.
  const Matrix3d R_RI = rig.imu ? Matrix3d(rig.imu->T_RS.rotation()) : Matrix3d::Identity();

  // 1. Read: IMU samples throughout, images from 0.5 s before the motion onset for `duration` s.
  const TimeNs range = from_seconds(o.offset_range_ms * 1e-3);
  const TimeNs pre = 500'000'000;
  OnsetDetector onset(o.onset_rate);
  std::vector<io::ImuSample> imu;
  std::deque<Frame> before;  // images of the last 0.5 s before the onset
  std::vector<Frame> frames;
  StreamTimes times;
  std::optional<TimeNs> t_first, window_start, onset_t;
  TimeNs window_end = 0;
  bool images_done = false;
  while (auto m = source.next()) {
    const TimeNs t = io::time_of(*m);
    if (!t_first) t_first = t;
    times.add(*m);
    if (auto* s = std::get_if<io::ImuSample>(&*m)) {
      if (!s->gyro.allFinite()) continue;
      imu.push_back(*s);
      if (!onset_t && onset.add(*s)) onset_t = s->t;
      // Done once the IMU covers the window's end plus the offset search range.
      if (images_done && s->t > window_end + t_d_configured + range + 100'000'000) break;
      continue;
    }
    auto* image = std::get_if<io::ImageFrame>(&*m);
    if (image == nullptr) continue;  // absolute fixes play no part in the calibration check
    auto& f = *image;
    if (f.camera != camera || images_done) continue;
    if (!onset_t) {
      if (t - *t_first > from_seconds(o.max_wait_s)) break;
      before.push_back(Frame{f.t, f.image});
      while (!before.empty() && f.t - before.front().t > pre) before.pop_front();
      continue;
    }
    if (!window_start) {
      frames.assign(before.begin(), before.end());
      before.clear();
      window_start = frames.empty() ? f.t : frames.front().t;
      window_end = *window_start + from_seconds(o.duration_s);
    }
    if (f.t > window_end) {
      images_done = true;
      continue;
    }
    frames.push_back(Frame{f.t, f.image});
    // IMU memory: drop what lies before the window's reach.
    if (imu.size() > 4096 && imu.front().t < *window_start - range - pre) {
      const auto keep = std::lower_bound(imu.begin(), imu.end(), *window_start - range - pre,
                                         [](const io::ImuSample& a, TimeNs tt) { return a.t < tt; });
      imu.erase(imu.begin(), keep);
    }
  }
  res.stream = times.report(o.gap_factor);
  res.stream.with_source_stats(source.stats());
  if (t_first && !frames.empty()) {
    res.window_start_s = to_seconds(frames.front().t - *t_first);
    res.window_end_s = to_seconds(frames.back().t - *t_first);
  }
  res.images = static_cast<int>(frames.size());
  if (res.stream.imu_samples == 0 || !rig.imu) return finish(Verdict::failed, "no IMU data");
  if (!onset_t) {
    return finish(Verdict::not_enough_motion, fmt::format("no motion within the first {:g} s", o.max_wait_s));
  }
  if (!window_start) {
    return finish(Verdict::not_enough_motion,
                  fmt::format("no image after the motion onset at {:.1f} s", to_seconds(*onset_t - *t_first)));
  }
  if (frames.size() < 20) return finish(Verdict::failed, fmt::format("{} images in the window", frames.size()));

  // 2. Camera rotation per image interval.
  const models::PinholeCamera cam(sim::to_intrinsics(cal));  // the io → models conversion, one place
  const auto pairs = track(frames, cam.intrinsics(), o);
  RelativeRotationOptions ro;
  ro.epipolar = o.epipolar;
  const double f_px = 0.5 * (cal.fx + cal.fy);
  ro.ransac_threshold = std::max(8.0 / f_px, 0.004);
  ro.sampson_threshold = std::max(1.5 / f_px, 0.0005);
  // The intervals' estimates are independent (each has its own generator, seeded by its index), so they run on
  // o.threads threads with the same results on any number of them (docs/performance.md has the time it saves).
  std::vector<RelativeRotation> rotations(pairs.size());
  std::vector<double> feats(pairs.size());
  const auto estimate = [&](std::size_t i) {
    std::vector<Vector3d> b0, b1;
    for (const auto& [p0, p1] : pairs[i]) {
      Vector3d r0, r1;
      if (cam.unproject(p0, r0) && cam.unproject(p1, r1)) {
        b0.push_back(r0.normalized());
        b1.push_back(r1.normalized());
      }
    }
    feats[i] = static_cast<double>(b0.size());
    Rng rng(17 + i);
    rotations[i] = estimate_relative_rotation(b0, b1, ro, rng);
  };
  if (!pairs.empty()) {
    std::atomic<std::size_t> next{0};
    std::exception_ptr failure;
    std::mutex failure_mu;
    const auto work = [&] {
      for (std::size_t i = next++; i < pairs.size(); i = next++) {
        try {
          estimate(i);
        } catch (...) {
          const std::lock_guard<std::mutex> lock(failure_mu);
          if (!failure) failure = std::current_exception();
          next = pairs.size();  // the others stop at their next interval
        }
      }
    };
    const std::size_t wanted = o.threads > 0 ? static_cast<std::size_t>(o.threads)
                                             : std::min(4u, std::max(1u, std::thread::hardware_concurrency()));
    {
      std::vector<std::jthread> helpers;  // joined when the scope ends, also when starting one throws
      for (std::size_t k = 1; k < std::min(wanted, pairs.size()); ++k) helpers.emplace_back(work);
      work();
    }
    if (failure) std::rethrow_exception(failure);
  }
  std::vector<VisualInterval> visual;
  std::vector<double> rms_px;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    VisualInterval v;
    v.t0 = frames[i].t;
    v.t1 = frames[i + 1].t;
    const RelativeRotation& rr = rotations[i];
    if (rr.ok) {
      v.valid = true;
      v.theta_C = math::log_so3(Eigen::Quaterniond(rr.R_01));
      rms_px.push_back(rr.rms * f_px);
    }
    visual.push_back(v);
  }
  res.intervals = static_cast<int>(visual.size());
  res.intervals_valid = static_cast<int>(std::count_if(visual.begin(), visual.end(), [](const auto& v) { return v.valid; }));
  res.median_features = median_of(feats);
  res.visual_rms_px = median_of(rms_px);
  if (res.intervals_valid < 20) {
    return finish(Verdict::failed, fmt::format("{} of {} image intervals gave a camera rotation", res.intervals_valid,
                                               res.intervals));
  }

  // 3. Time offset from the rate magnitudes (rotation-invariant), around the configured one.
  const double step = 1e-3;
  const TimeOffsetResult to = estimate_time_offset(visual, imu, to_seconds(t_d_configured), o.offset_range_ms * 1e-3,
                                                   step);
  res.correlation = to.correlation;
  res.second_peak_correlation = to.second_best;
  double t_d = to_seconds(t_d_configured);
  // The magnitudes alone are trusted when their peak stands out; a smooth motion gives a broad curve with several
  // near-equal peaks, which the vector residual (below, once the rotation is known) resolves.
  const bool correlated = to.ok && to.correlation >= o.min_correlation;
  const bool unambiguous = correlated && to.correlation - to.second_best >= 0.02;
  if (unambiguous) t_d = to.t_d_s;
  res.offset_measured = unambiguous;

  // 4. Hand-eye rotation at that offset; then the offset refined on the full rate vectors, and the rotation again.
  const auto hand_eye = [&](double t_d_s, const Vector3d& bias) {
    std::vector<Vector3d> wC, wR;
    std::vector<double> w;
    for (const VisualInterval& v : visual) {
      if (!v.valid) continue;
      const TimeNs d = from_seconds(t_d_s);
      const auto th = integrate_gyro(imu, v.t0 + d, v.t1 + d, bias);
      if (!th) continue;
      const double dt = to_seconds(v.t1 - v.t0);
      wC.push_back(v.theta_C / dt);
      wR.push_back(R_RI * *th / dt);
      w.push_back(v.weight);
    }
    return estimate_hand_eye_rotation(wC, wR, w, o.min_excitation);
  };
  HandEyeResult he = hand_eye(t_d, Vector3d::Zero());
  if (he.ok && correlated) {
    res.offset_measured = true;
    // The bias is in R; integrate_gyro removes it in the gyro's frame I.
    // Over the whole range first (the magnitudes' peak is broad when the motion is smooth), then near the result.
    for (const double half_range : {o.offset_range_ms * 1e-3, 0.01}) {
      if (!he.ok) break;
      const Vector3d bias_I = R_RI.transpose() * he.gyro_bias;
      const Matrix3d R_IS = R_RI.transpose() * he.R_RS;
      const double centre = half_range > 0.01 ? to_seconds(t_d_configured) : t_d;
      if (const auto refined = refine_time_offset(visual, imu, R_IS, bias_I, centre, half_range, step)) {
        t_d = *refined;
        he = hand_eye(t_d, Vector3d::Zero());
      }
    }
  }
  res.excitation_rad_s = he.excitation_rad_s;
  // Measured when the fit can decide at the tolerance: its std well below it.
  res.rotation_measured = he.ok && he.rotation_std_deg <= o.max_rotation_deg / 3.0;
  res.rotation_std_deg = he.rotation_std_deg;
  if (res.rotation_measured) {
    res.R_RS_measured = he.R_RS;
    res.rotation_std_deg = he.rotation_std_deg;
    res.rate_rms_rad_s = he.rms_rad_s;
    res.gyro_bias = he.gyro_bias;
    res.rotation_error_deg = angle_between_deg(he.R_RS, res.R_RS_configured);
    res.rotation_to_inverse_deg = angle_between_deg(he.R_RS, res.R_RS_configured.transpose());
    res.looks_inverted = res.rotation_error_deg > o.max_rotation_deg && res.rotation_to_inverse_deg <= o.max_rotation_deg;
  }
  // Without the rotation to confirm them the magnitudes alone decide nothing: with little rotation the camera's
  // rates carry the parallax of the translation, whose phase differs from the rotation's (a peak 22 ms off on rendered
  // handheld motion). Their peak is kept as information (t_d_measured_ms), never warned about.
  bool offset_magnitudes_only = false;
  if (!res.rotation_measured && res.offset_measured) {
    res.offset_measured = false;
    offset_magnitudes_only = true;
    res.t_d_measured_ms = t_d * 1e3;
  }
  if (res.offset_measured) {
    res.t_d_measured_ms = t_d * 1e3;
    res.offset_error_ms = res.t_d_measured_ms - res.t_d_configured_ms;
  }

  // Verdict.
  if (res.rotation_measured && res.rotation_error_deg > o.max_rotation_deg) {
    const Eigen::Quaterniond qm(res.R_RS_measured), qc(res.R_RS_configured);
    res.warnings.push_back(fmt::format(
        "the camera–IMU rotation measured from the data is {:.1f} deg from the configured T_RS (tolerance {:g} deg){}: "
        "measured q_RS (w x y z) = ({:.4f} {:.4f} {:.4f} {:.4f}), configured ({:.4f} {:.4f} {:.4f} {:.4f})",
        res.rotation_error_deg, o.max_rotation_deg,
        res.looks_inverted ? fmt::format("; it looks like the inverse of T_RS (measured {:.1f} deg from T_RS⁻¹): "
                                         "a T_SR given where T_RS is expected?",
                                         res.rotation_to_inverse_deg)
                           : std::string(),
        qm.w(), qm.x(), qm.y(), qm.z(), qc.w(), qc.x(), qc.y(), qc.z()));
  }
  if (res.offset_measured && std::abs(res.offset_error_ms) > o.max_offset_ms) {
    res.warnings.push_back(fmt::format(
        "the camera–IMU time offset measured from the data is t_d = {:.1f} ms, the configuration says {:.1f} ms "
        "(difference {:+.1f} ms, tolerance {:g} ms; t_imu = t_cam + t_d: set imu/time_offset: {:.4f})",
        res.t_d_measured_ms, res.t_d_configured_ms, res.offset_error_ms, o.max_offset_ms, res.t_d_measured_ms * 1e-3));
  }
  std::string why;
  if (!res.rotation_measured) {
    why = fmt::format("not enough rotation about two axes for the camera–IMU rotation ({:.2f} rad/s, need {:g}; "
                      "std {:.1f} deg, need <= {:.1f})",
                      res.excitation_rad_s, o.min_excitation, res.rotation_std_deg, o.max_rotation_deg / 3.0);
  }
  if (offset_magnitudes_only) {
    why += fmt::format("; the time offset needs the rotation (the rate magnitudes alone peak at {:.1f} ms)",
                       res.t_d_measured_ms);
  } else if (!res.offset_measured && correlated) {
    why += fmt::format("{}the rate magnitudes peak ambiguously for the time offset (correlation {:.2f}, another peak "
                       "{:.2f})", why.empty() ? "" : "; ", res.correlation, res.second_peak_correlation);
  } else if (!res.offset_measured) {
    why += fmt::format("{}the camera and gyro rates do not correlate enough for the time offset ({:.2f}, need {:g})",
                       why.empty() ? "" : "; ", res.correlation, o.min_correlation);
  }
  logger("calib")->debug("calibration check: rotation error {:.2f} deg, t_d {:.2f} ms, {} ms", res.rotation_error_deg,
                         res.t_d_measured_ms, res.cost_ms);
  if (!res.warnings.empty()) return finish(Verdict::warning, why);
  if (!why.empty()) return finish(Verdict::not_enough_motion, why);
  return finish(Verdict::ok, "");
}

CheckResult check_dataset_calibration(const std::string& spec, io::DatasetOptions dopt, int camera,
                                      std::optional<TimeNs> t_d_configured, const CheckOptions& o,
                                      int prefetch_threads) {
  const auto clock0 = std::chrono::steady_clock::now();
  dopt.cameras = {camera};
  dopt.use_imu = true;
  dopt.duration_s = 0.0;  // the check reads what it needs (start_offset_s is kept: the run's start)
  io::Dataset ds = io::open_dataset(spec, dopt);
  // Images decoded ahead while the check tracks the ones before, as the run reads them (the stream is the same).
  io::start_prefetch(ds.source, prefetch_threads);
  CheckResult r = check_calibration(*ds.source, ds.rig, 0, t_d_configured.value_or(ds.rig.t_d), o);
  r.cost_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - clock0).count();
  return r;
}

}  // namespace rtslam::calib
