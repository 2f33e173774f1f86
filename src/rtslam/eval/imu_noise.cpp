#include "rtslam/eval/imu_noise.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/eval/geometry.hpp"
#include "rtslam/io/dataset.hpp"

namespace rtslam::eval {
namespace {

namespace fs = std::filesystem;
using Eigen::Quaterniond;
using Eigen::Vector3d;

/// q = Exp(θ) (Hamilton, unit), first-order series near zero.
Quaterniond exp_so3(const Vector3d& theta) {
  const double n = theta.norm();
  if (n < 1e-10) return Quaterniond(1.0, 0.5 * theta.x(), 0.5 * theta.y(), 0.5 * theta.z()).normalized();
  return Quaterniond(Eigen::AngleAxisd(n, theta / n));
}

/// The IMU reading at t (t within the samples' span), linear between the two samples around it.
io::ImuSample sample_at(const std::vector<io::ImuSample>& imu, TimeNs t) {
  auto it = std::upper_bound(imu.begin(), imu.end(), t, [](TimeNs a, const io::ImuSample& s) { return a < s.t; });
  if (it == imu.begin()) return imu.front();
  if (it == imu.end()) return imu.back();
  const io::ImuSample& b = *it;
  const io::ImuSample& a = *(it - 1);
  const double w = static_cast<double>(t - a.t) / static_cast<double>(b.t - a.t);
  io::ImuSample s;
  s.t = t;
  s.gyro = (1.0 - w) * a.gyro + w * b.gyro;
  s.accel = (1.0 - w) * a.accel + w * b.accel;
  return s;
}

struct Integrated {
  Quaterniond q_WR;
  Vector3d v_WR;
};

/// Midpoint integration of the samples of [t0, t1] from the state `s` with its biases (see the header).
Integrated integrate(const std::vector<io::ImuSample>& imu, const StampedPose& s, TimeNs t1, const Vector3d& g_W) {
  const Vector3d& b_w = *s.gyro_bias;
  const Vector3d& b_a = *s.accel_bias;
  Quaterniond q = s.q_WR.normalized();
  Vector3d v = *s.v_WR;
  io::ImuSample prev = sample_at(imu, s.t);
  auto it = std::upper_bound(imu.begin(), imu.end(), s.t, [](TimeNs a, const io::ImuSample& x) { return a < x.t; });
  while (prev.t < t1) {
    const io::ImuSample next = (it != imu.end() && it->t < t1) ? *it++ : sample_at(imu, t1);
    const double dt = to_seconds(next.t - prev.t);
    const Vector3d w = 0.5 * (prev.gyro + next.gyro) - b_w;
    const Quaterniond q_next = (q * exp_so3(w * dt)).normalized();
    const Vector3d a = 0.5 * (q * (prev.accel - b_a) + q_next * (next.accel - b_a)) + g_W;
    v += a * dt;
    q = q_next;
    prev = next;
  }
  return {q, v};
}

struct Accumulator {
  int n = 0;
  double sum_th2 = 0.0, sum_v2 = 0.0;  // Σ |δ|² / (3 T)
  Vector3d sum_th = Vector3d::Zero(), sum_v = Vector3d::Zero();
  void add(const Vector3d& dth, const Vector3d& dv, double T) {
    ++n;
    sum_th2 += dth.squaredNorm() / (3.0 * T);
    sum_v2 += dv.squaredNorm() / (3.0 * T);
    sum_th += dth;
    sum_v += dv;
  }
  ImuNoiseFigures figures() const {
    ImuNoiseFigures f;
    f.windows = n;
    if (n == 0) return f;
    f.gyro_density = std::sqrt(sum_th2 / n);
    f.accel_density = std::sqrt(sum_v2 / n);
    f.mean_rotation_residual = sum_th / n;
    f.mean_velocity_residual = sum_v / n;
    return f;
  }
};

double median_period_s(const std::vector<io::ImuSample>& imu) {
  std::vector<TimeNs> d;
  d.reserve(imu.size());
  for (std::size_t i = 1; i < imu.size(); ++i) d.push_back(imu[i].t - imu[i - 1].t);
  if (d.empty()) return 0.0;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return to_seconds(d[d.size() / 2]);
}

std::string sci(double x) { return fmt::format("{:.2e}", x); }

}  // namespace

void ImuNoiseOptions::validate() const {
  const std::string w = "imu-noise";
  if (windows_s.empty()) throw ConfigError("imu-noise: --windows must list at least one window length (s)");
  for (double T : windows_s) require_bound(T > 0.0 && T <= 100.0, w, "window", T, "in (0, 100] s");
  require_bound(from_s >= 0.0, w, "from", from_s, ">= 0 s");
  require_bound(to_s == 0.0 || to_s > from_s, w, "to", to_s, "0 (the end) or > from");
  require_bound(rest_speed > 0.0, w, "rest_speed", rest_speed, "> 0 m/s");
  require_bound(gravity > 0.0 && gravity < 30.0, w, "gravity", gravity, "in (0, 30) m/s²");
  require_bound(window_tolerance > 0.0 && window_tolerance < 0.5, w, "window_tolerance", window_tolerance,
                "in (0, 0.5)");
}

ImuNoiseReport measure_imu_noise(const std::vector<io::ImuSample>& imu, const Trajectory& states,
                                 const ImuNoiseOptions& o) {
  o.validate();
  const std::string src = states.source.empty() ? std::string("ground truth") : states.source;
  if (imu.size() < 2) throw DataError("imu-noise: fewer than 2 IMU samples");
  for (std::size_t i = 1; i < imu.size(); ++i) {
    if (imu[i].t <= imu[i - 1].t)
      throw DataError(fmt::format("imu-noise: IMU sample {} (t = {} ns) is not after the previous one", i, imu[i].t));
  }
  if (states.poses.size() < 2) throw DataError(fmt::format("{}: fewer than 2 ground-truth states", src));
  for (std::size_t k = 0; k < states.poses.size(); ++k) {
    const StampedPose& s = states.poses[k];
    if (!s.v_WR || !s.gyro_bias || !s.accel_bias)
      throw DataError(fmt::format("{}: state {} (t = {} ns) has no {}: imu-noise needs EuRoC states "
                                  "(t, p, q, v, b_w, b_a)",
                                  src, k, s.t, !s.v_WR ? "velocity" : "biases"));
    if (k > 0 && s.t <= states.poses[k - 1].t)
      throw DataError(fmt::format("{}: state {} (t = {} ns) is not after the previous one", src, k, s.t));
  }

  ImuNoiseReport r;
  r.imu_samples = static_cast<int>(imu.size());
  r.imu_period_s = median_period_s(imu);
  r.rest_speed = o.rest_speed;
  const TimeNs gap = from_seconds(2.5 * r.imu_period_s);
  // gaps_before[i]: IMU steps longer than `gap` among the steps ending at samples 1..i.
  std::vector<int> gaps_before(imu.size(), 0);
  for (std::size_t i = 1; i < imu.size(); ++i) gaps_before[i] = gaps_before[i - 1] + (imu[i].t - imu[i - 1].t > gap);
  const auto index_after = [&](TimeNs t) {  // first sample with time > t
    return static_cast<std::size_t>(
        std::upper_bound(imu.begin(), imu.end(), t, [](TimeNs a, const io::ImuSample& s) { return a < s.t; }) -
        imu.begin());
  };

  const std::vector<StampedPose>& S = states.poses;
  const TimeNs t_first = S.front().t;
  const TimeNs t_from = t_first + from_seconds(o.from_s);
  const TimeNs t_to = o.to_s > 0.0 ? t_first + from_seconds(o.to_s) : S.back().t;
  // moving_before[k]: states at or above rest_speed among 0..k-1.
  std::vector<int> moving_before(S.size() + 1, 0);
  TimeNs used_begin = -1, used_end = -1;
  for (std::size_t k = 0; k < S.size(); ++k) {
    moving_before[k + 1] = moving_before[k] + (S[k].v_WR->norm() >= o.rest_speed);
    if (S[k].t >= t_from && S[k].t <= t_to) {
      ++r.states;
      if (used_begin < 0) used_begin = S[k].t;
      used_end = S[k].t;
    }
  }
  r.span_s = used_begin < 0 ? 0.0 : to_seconds(used_end - used_begin);
  const Vector3d g_W(0.0, 0.0, -o.gravity);

  for (double T : o.windows_s) {
    ImuNoiseWindow win;
    win.window_s = T;
    Accumulator all, rest, flight;
    const TimeNs dT = from_seconds(T);
    const TimeNs tol = from_seconds(o.window_tolerance * T);
    for (std::size_t k = 0; k < S.size(); ++k) {
      const StampedPose& a = S[k];
      if (a.t < t_from || a.t < imu.front().t) continue;
      const TimeNs target = a.t + dT;
      if (target - tol > t_to || target - tol > imu.back().t) break;
      // The state nearest to t_k + T, within the tolerance.
      auto it = std::lower_bound(S.begin() + static_cast<std::ptrdiff_t>(k) + 1, S.end(), target,
                                 [](const StampedPose& s, TimeNs t) { return s.t < t; });
      std::size_t j = static_cast<std::size_t>(it - S.begin());
      if (j == S.size() || (j > k + 1 && target - S[j - 1].t < S[j].t - target)) --j;
      if (j <= k || std::llabs(S[j].t - target) > tol || S[j].t > t_to || S[j].t > imu.back().t) continue;
      const StampedPose& b = S[j];
      // Samples bracketing [t_k, t_j]: no gap allowed between them.
      const std::size_t i0 = std::max<std::size_t>(index_after(a.t), 1) - 1;
      const std::size_t i1 = std::min(index_after(b.t - 1), imu.size() - 1);
      if (gaps_before[i1] - gaps_before[i0] > 0) {
        ++win.skipped_gaps;
        continue;
      }
      const Integrated e = integrate(imu, a, b.t, g_W);
      const Vector3d dth = so3_log(e.q_WR.conjugate() * b.q_WR.normalized());
      const Vector3d dv = *b.v_WR - e.v_WR;
      const double Tk = to_seconds(b.t - a.t);
      all.add(dth, dv, Tk);
      const bool moving = moving_before[j + 1] - moving_before[k] > 0;
      (moving ? flight : rest).add(dth, dv, Tk);
    }
    win.all = all.figures();
    win.rest = rest.figures();
    win.flight = flight.figures();
    r.windows.push_back(win);
  }
  if (r.states < 2) {
    throw DataError(fmt::format("{}: {} ground-truth state(s) from {} s after the first one to {}", src, r.states,
                                o.from_s, o.to_s > 0.0 ? fmt::format("{} s", o.to_s) : std::string("the end")));
  }
  if (std::all_of(r.windows.begin(), r.windows.end(), [](const ImuNoiseWindow& w) { return w.all.windows == 0; })) {
    throw DataError(fmt::format("{}: no window of ground-truth states is covered by the IMU samples (states {:.3f}–"
                                "{:.3f} s, IMU {:.3f}–{:.3f} s, in seconds of the recording's clock)",
                                src, to_seconds(S.front().t), to_seconds(S.back().t), to_seconds(imu.front().t),
                                to_seconds(imu.back().t)));
  }

  // The suggestion: white noise from the shortest window, random walks from the window closest to 1 s.
  std::size_t shortest = 0, near_1s = 0;
  for (std::size_t i = 0; i < r.windows.size(); ++i) {
    const ImuNoiseWindow& w = r.windows[i];
    if (w.all.windows == 0) continue;
    if (r.windows[shortest].all.windows == 0 || w.window_s < r.windows[shortest].window_s) shortest = i;
    if (r.windows[near_1s].all.windows == 0 ||
        std::abs(std::log(w.window_s)) < std::abs(std::log(r.windows[near_1s].window_s)))
      near_1s = i;
  }
  r.rest_and_flight = r.windows[shortest].rest.windows > 0 && r.windows[shortest].flight.windows > 0;
  const auto subset = [&](const ImuNoiseWindow& w) -> const ImuNoiseFigures& {
    return r.rest_and_flight && w.flight.windows > 0 ? w.flight : w.all;
  };
  ImuNoiseSuggestion s;
  s.accelerometer_noise_density = subset(r.windows[shortest]).accel_density;
  s.gyroscope_noise_density = subset(r.windows[shortest]).gyro_density;
  s.basis = fmt::format("{} windows: densities from {:g} ms", r.rest_and_flight ? "in-flight" : "all",
                        1e3 * r.windows[shortest].window_s);
  if (r.windows[near_1s].window_s >= 0.5) {
    s.accelerometer_random_walk = subset(r.windows[near_1s]).accel_density;
    s.gyroscope_random_walk = subset(r.windows[near_1s]).gyro_density;
    s.basis += fmt::format(", random walks from {:g} ms", 1e3 * r.windows[near_1s].window_s);
  } else {
    s.basis += "; random walks need a window of about 1 s";
  }
  r.suggestion = s;
  return r;
}

ImuNoiseInput read_imu_noise_input(const std::string& spec) {
  std::string dir = spec;
  const auto colon = spec.find(':');
  if (colon != std::string::npos && colon > 1) {  // "KIND:PATH" (a one-letter prefix is a drive, not a kind)
    const std::string kind = spec.substr(0, colon);
    if (kind != "euroc")
      throw ConfigError(fmt::format("imu-noise: dataset '{}': only EuRoC folders (euroc:DIR) carry ground-truth "
                                    "states with velocity and biases",
                                    spec));
    dir = spec.substr(colon + 1);
  }
  if (!fs::is_directory(dir)) throw IoError(fmt::format("{}: dataset folder not found", dir));
  const fs::path root = fs::is_directory(fs::path(dir) / "mav0") ? fs::path(dir) / "mav0" : fs::path(dir);
  const fs::path imu_csv = root / "imu0" / "data.csv";
  const fs::path states_csv = root / "state_groundtruth_estimate0" / "data.csv";
  if (!fs::is_regular_file(imu_csv))
    throw IoError(fmt::format("{}: not found (imu-noise needs the recorded IMU)", imu_csv.string()));
  if (!fs::is_regular_file(states_csv))
    throw IoError(fmt::format("{}: not found (imu-noise needs the ground-truth states t, p, q, v, b_w, b_a)",
                              states_csv.string()));
  // The states are of EuRoC's body frame B; the IMU must be B itself (EuRoC's imu0 T_BS is the identity).
  const fs::path imu_yaml = root / "imu0" / "sensor.yaml";
  if (fs::is_regular_file(imu_yaml)) {
    const io::ImuCalibration cal = io::load_euroc_imu(imu_yaml.string());
    if (!cal.T_RS.matrix().isApprox(Eigen::Matrix4d::Identity(), 1e-9))
      throw DataError(fmt::format("{}: T_BS is not the identity: the ground-truth states are not of the IMU frame",
                                  imu_yaml.string()));
  }
  io::DatasetOptions opts;
  opts.cameras = {};
  io::Dataset ds = io::open_dataset("euroc:" + dir, opts);
  ImuNoiseInput in;
  in.calibration = ds.rig.imu;
  while (auto m = ds.source->next()) {
    if (const auto* s = std::get_if<io::ImuSample>(&*m)) in.imu.push_back(*s);
  }
  if (in.imu.empty()) throw DataError(fmt::format("{}: no IMU sample", imu_csv.string()));
  if (!ds.ground_truth) throw IoError(fmt::format("{}: could not be read", states_csv.string()));
  in.states = std::move(*ds.ground_truth);
  if (in.states.source.empty()) in.states.source = states_csv.string();
  return in;
}

std::string format_imu_noise(const ImuNoiseReport& r, const std::optional<io::ImuCalibration>& cal) {
  std::string out = fmt::format(
      "imu-noise: {} ground-truth states over {:.1f} s, {} IMU samples (median period {:.3f} ms); windows at rest: "
      "ground-truth speed below {:g} m/s throughout\n",
      r.states, r.span_s, r.imu_samples, 1e3 * r.imu_period_s, r.rest_speed);
  out += fmt::format("{:>9}  {:<9} {:>6}  {:>16}  {:>16}  {:>22}  {:>22}\n", "window", "subset", "n",
                     "gyro rad/s/√Hz", "accel m/s²/√Hz", "mean δθ (mrad)", "mean δv (mm/s)");
  const auto row = [&](const std::string& T, const char* name, const ImuNoiseFigures& f) {
    if (f.windows == 0) return;
    const Vector3d th = 1e3 * f.mean_rotation_residual, v = 1e3 * f.mean_velocity_residual;
    out += fmt::format("{:>9}  {:<9} {:>6}  {:>16}  {:>16}  {:>22}  {:>22}\n", T, name, f.windows, sci(f.gyro_density),
                       sci(f.accel_density), fmt::format("{:.2f} {:.2f} {:.2f}", th.x(), th.y(), th.z()),
                       fmt::format("{:.1f} {:.1f} {:.1f}", v.x(), v.y(), v.z()));
  };
  for (const ImuNoiseWindow& w : r.windows) {
    const std::string T = fmt::format("{:g} ms", 1e3 * w.window_s);
    row(T, "all", w.all);
    if (r.rest_and_flight) {
      row("", "at rest", w.rest);
      row("", "in flight", w.flight);
    }
    if (w.all.windows == 0) out += fmt::format("{:>9}  no window\n", T);
    if (w.skipped_gaps > 0) out += fmt::format("{:>9}  {} window(s) over an IMU gap skipped\n", "", w.skipped_gaps);
  }
  if (cal) {
    out += fmt::format("calibration (sensor.yaml): gyroscope_noise_density {}, accelerometer_noise_density {}, "
                       "gyroscope_random_walk {}, accelerometer_random_walk {}\n",
                       sci(cal->gyro_noise_density), sci(cal->accel_noise_density), sci(cal->gyro_random_walk),
                       sci(cal->accel_random_walk));
  }
  if (r.suggestion) {
    const ImuNoiseSuggestion& s = *r.suggestion;
    out += fmt::format("suggested imu: section ({}):\n", s.basis);
    out += fmt::format("  accelerometer_noise_density: {:.1e}   # m/s2/sqrt(Hz)\n", s.accelerometer_noise_density);
    out += fmt::format("  gyroscope_noise_density: {:.1e}       # rad/s/sqrt(Hz)\n", s.gyroscope_noise_density);
    if (s.accelerometer_random_walk && s.gyroscope_random_walk) {
      out += fmt::format("  accelerometer_random_walk: {:.1e}     # m/s3/sqrt(Hz)\n", *s.accelerometer_random_walk);
      out += fmt::format("  gyroscope_random_walk: {:.1e}         # rad/s2/sqrt(Hz)\n", *s.gyroscope_random_walk);
    }
  }
  return out;
}

nlohmann::json to_json(const ImuNoiseReport& r) {
  const auto fig = [](const ImuNoiseFigures& f) {
    nlohmann::json j;
    j["windows"] = f.windows;
    j["gyro_density"] = f.gyro_density;
    j["accel_density"] = f.accel_density;
    j["mean_rotation_residual_rad"] = {f.mean_rotation_residual.x(), f.mean_rotation_residual.y(),
                                       f.mean_rotation_residual.z()};
    j["mean_velocity_residual_m_s"] = {f.mean_velocity_residual.x(), f.mean_velocity_residual.y(),
                                       f.mean_velocity_residual.z()};
    return j;
  };
  nlohmann::json j;
  j["states"] = r.states;
  j["imu_samples"] = r.imu_samples;
  j["span_s"] = r.span_s;
  j["imu_period_s"] = r.imu_period_s;
  j["rest_speed_m_s"] = r.rest_speed;
  j["rest_and_flight"] = r.rest_and_flight;
  j["windows"] = nlohmann::json::array();
  for (const ImuNoiseWindow& w : r.windows) {
    nlohmann::json jw;
    jw["window_s"] = w.window_s;
    jw["all"] = fig(w.all);
    jw["rest"] = fig(w.rest);
    jw["flight"] = fig(w.flight);
    jw["skipped_gaps"] = w.skipped_gaps;
    j["windows"].push_back(jw);
  }
  if (r.suggestion) {
    const ImuNoiseSuggestion& s = *r.suggestion;
    j["suggestion"] = {{"accelerometer_noise_density", s.accelerometer_noise_density},
                       {"gyroscope_noise_density", s.gyroscope_noise_density},
                       {"basis", s.basis}};
    if (s.accelerometer_random_walk) j["suggestion"]["accelerometer_random_walk"] = *s.accelerometer_random_walk;
    if (s.gyroscope_random_walk) j["suggestion"]["gyroscope_random_walk"] = *s.gyroscope_random_walk;
  }
  return j;
}

}  // namespace rtslam::eval
