#include "rtslam/sim/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/io/trajectory_io.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::sim {

using Eigen::Matrix3d;
using Eigen::Quaterniond;
using Eigen::Vector3d;

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

// Smootherstep S(s) = 6s^5 − 15s^4 + 10s^3 on [0, 1] (0 below, 1 above) and its derivatives in s.
void smootherstep(double s, double& v, double& d1, double& d2) {
  if (s <= 0.0) {
    v = d1 = d2 = 0.0;
  } else if (s >= 1.0) {
    v = 1.0;
    d1 = d2 = 0.0;
  } else {
    v = s * s * s * (10.0 + s * (-15.0 + 6.0 * s));
    d1 = 30.0 * s * s * (1.0 - s) * (1.0 - s);
    d2 = 60.0 * s * (1.0 - s) * (1.0 - 2.0 * s);
  }
}

// Envelope of a wave (product of a rising and a falling smootherstep) and its time derivatives.
void envelope(const Wave& w, double t, double& e, double& e1, double& e2) {
  if (t < w.t_on_s || t > w.t_off_s) {
    e = e1 = e2 = 0.0;
    return;
  }
  if (w.ramp_s <= 0.0) {
    e = 1.0;
    e1 = e2 = 0.0;
    return;
  }
  double r, r1, r2, f, f1, f2;
  smootherstep((t - w.t_on_s) / w.ramp_s, r, r1, r2);
  smootherstep((w.t_off_s - t) / w.ramp_s, f, f1, f2);
  r1 /= w.ramp_s;
  r2 /= w.ramp_s * w.ramp_s;
  f1 = -f1 / w.ramp_s;  // d/dt of S((t_off − t)/ramp)
  f2 /= w.ramp_s * w.ramp_s;
  e = r * f;
  e1 = r1 * f + r * f1;
  e2 = r2 * f + 2.0 * r1 * f1 + r * f2;
}

// Uniform cubic cumulative B-spline basis B̃1..B̃3 at u in [0, 1] and their u-derivatives.
void cumulative_basis(double u, Vector3d& b, Vector3d& b1, Vector3d& b2) {
  const double u2 = u * u, u3 = u2 * u;
  b << (5.0 + 3.0 * u - 3.0 * u2 + u3) / 6.0, (1.0 + 3.0 * u + 3.0 * u2 - 2.0 * u3) / 6.0, u3 / 6.0;
  b1 << (3.0 - 6.0 * u + 3.0 * u2) / 6.0, (3.0 + 6.0 * u - 6.0 * u2) / 6.0, 0.5 * u2;
  b2 << (-1.0 + u), (1.0 - 2.0 * u), u;
}

}  // namespace

double WaveChannel::eval(double t, double& d1, double& d2) const {
  double v = offset;
  d1 = d2 = 0.0;
  for (const Wave& w : waves) {
    double e, e1, e2;
    envelope(w, t, e, e1, e2);
    if (e == 0.0 && e1 == 0.0 && e2 == 0.0) continue;
    const double om = kTwoPi * w.freq_hz;
    const double arg = om * t + w.phase_rad;
    const double s = w.amplitude * std::sin(arg);
    const double s1 = w.amplitude * om * std::cos(arg);
    const double s2 = -om * om * s;
    v += e * s;
    d1 += e1 * s + e * s1;
    d2 += e2 * s + 2.0 * e1 * s1 + e * s2;
  }
  return v;
}

WaveTrajectory::WaveTrajectory(WaveTrajectoryParams params) : params_(std::move(params)) {
  if (!(params_.duration_s > 0.0))
    throw ConfigError(fmt::format("trajectory '{}': duration = {} s must be > 0", params_.name, params_.duration_s));
}

Matrix3d WaveTrajectory::base_rotation() {
  Matrix3d R;  // columns: images of R's x, y, z axes in W
  R << 0.0, 0.0, 1.0,  //
      0.0, -1.0, 0.0,  //
      1.0, 0.0, 0.0;
  return R;
}

KinematicState WaveTrajectory::at(TimeNs t_ns) const {
  const TimeNs tc = std::clamp(t_ns, t_begin(), t_end());
  const double t = to_seconds(tc - params_.t_begin);
  // Time warp τ(t) for a start at rest: τ' = S(t/T), τ = T·∫S (∫S(s) = s^6 − 3s^5 + 2.5s^4, 1/2 at s = 1).
  double tau = t, tau1 = 1.0, tau2 = 0.0;
  if (params_.warmup_s > 0.0 && t < params_.warmup_s) {
    const double T = params_.warmup_s, x = t / T;
    double d1, d2;
    smootherstep(x, tau1, d1, d2);
    tau = T * x * x * x * x * (2.5 + x * (-3.0 + x));
    tau2 = d1 / T;
  } else if (params_.warmup_s > 0.0) {
    tau = t - 0.5 * params_.warmup_s;
  }
  auto channel = [&](const WaveChannel& c, double& d1, double& d2) {
    double f1, f2;
    const double v = c.eval(tau, f1, f2);
    d1 = f1 * tau1;
    d2 = f2 * tau1 * tau1 + f1 * tau2;
    return v;
  };
  KinematicState s;
  s.t = t_ns;
  for (int i = 0; i < 3; ++i) s.p_WR[i] = channel(params_.position[i], s.v_WR[i], s.a_WR[i]);

  double y1, y2, p1, p2, r1, r2;
  const double y = channel(params_.yaw, y1, y2);
  const double p = channel(params_.pitch, p1, p2);
  const double r = channel(params_.roll, r1, r2);
  const Matrix3d R_WE = (Eigen::AngleAxisd(y, Vector3d::UnitZ()) * Eigen::AngleAxisd(p, Vector3d::UnitY()) *
                         Eigen::AngleAxisd(r, Vector3d::UnitX()))
                            .toRotationMatrix();
  const Matrix3d R_base = base_rotation();
  s.q_WR = Quaterniond(R_WE * R_base).normalized();

  // Body rates of the ZYX Euler frame E, then rotated into R (R_WR = R_WE R_base => w_R = R_baseᵀ w_E).
  const double sp = std::sin(p), cp = std::cos(p), sr = std::sin(r), cr = std::cos(r);
  const Vector3d w_E(r1 - y1 * sp, p1 * cr + y1 * sr * cp, -p1 * sr + y1 * cr * cp);
  const Vector3d dw_E(r2 - y2 * sp - y1 * cp * p1,
                      p2 * cr - p1 * sr * r1 + y2 * sr * cp + y1 * cr * r1 * cp - y1 * sr * sp * p1,
                      -p2 * sr - p1 * cr * r1 + y2 * cr * cp - y1 * sr * r1 * cp - y1 * cr * sp * p1);
  s.w_R = R_base.transpose() * w_E;
  s.dw_R = R_base.transpose() * dw_E;
  if (tc != t_ns) {  // clamped outside the domain: hold the end pose at rest
    s.v_WR.setZero();
    s.a_WR.setZero();
    s.w_R.setZero();
    s.dw_R.setZero();
  }
  return s;
}

SplineTrajectory::SplineTrajectory(TimeNs t0, TimeNs dt, std::vector<Quaterniond> q_WR, std::vector<Vector3d> p_WR,
                                   std::string name)
    : t0_(t0), dt_(dt), q_(std::move(q_WR)), p_(std::move(p_WR)), name_(std::move(name)) {
  if (q_.size() != p_.size() || q_.size() < 4)
    throw DataError(fmt::format("{}: a B-spline needs at least 4 control poses (got {})", name_, q_.size()));
  if (dt_ <= 0) throw DataError(fmt::format("{}: knot spacing {} ns must be > 0", name_, dt_));
  omega_.assign(q_.size(), Vector3d::Zero());
  for (std::size_t k = 0; k < q_.size(); ++k) {
    q_[k].normalize();
    if (k > 0) {
      if (q_[k].coeffs().dot(q_[k - 1].coeffs()) < 0.0) q_[k].coeffs() = -q_[k].coeffs();
      omega_[k] = math::log_so3(q_[k - 1].conjugate() * q_[k]);
    }
  }
}

SplineTrajectory SplineTrajectory::from_recorded(const Trajectory& rec, TimeNs dt) {
  const auto& P = rec.poses;
  if (P.size() < 2 || P.back().t - P.front().t < 4 * dt)
    throw DataError(fmt::format("{}: trajectory too short to follow ({} poses, {:.3f} s; need > {:.3f} s)", rec.source,
                                P.size(), P.empty() ? 0.0 : to_seconds(P.back().t - P.front().t),
                                to_seconds(4 * dt)));
  for (std::size_t i = 1; i < P.size(); ++i)
    if (P[i].t <= P[i - 1].t)
      throw DataError(fmt::format("{}: timestamps not increasing at pose {} (t = {} ns)", rec.source, i, P[i].t));
  const TimeNs t0 = P.front().t;
  const auto n = static_cast<std::size_t>((P.back().t - t0) / dt) + 1;
  std::vector<Quaterniond> qs;
  std::vector<Vector3d> ps;
  qs.reserve(n);
  ps.reserve(n);
  std::size_t j = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const TimeNs tk = t0 + static_cast<TimeNs>(k) * dt;
    while (j + 2 < P.size() && P[j + 1].t < tk) ++j;
    const std::size_t j1 = std::min(j + 1, P.size() - 1);
    const double a = j1 == j ? 0.0 : std::clamp(to_seconds(tk - P[j].t) / to_seconds(P[j1].t - P[j].t), 0.0, 1.0);
    const Quaterniond q_interp = P[j].q_WR.normalized().slerp(a, P[j1].q_WR.normalized());
    // Average the recorded poses within ±dt/2 around the interpolated one (a box pre-filter against mocap noise).
    Vector3d p_sum = Vector3d::Zero(), th_sum = Vector3d::Zero();
    int count = 0;
    std::size_t lo = j;
    while (lo > 0 && P[lo].t >= tk - dt / 2) --lo;
    for (std::size_t m = lo; m < P.size() && P[m].t <= tk + dt / 2; ++m) {
      if (P[m].t < tk - dt / 2) continue;
      p_sum += P[m].p_WR;
      th_sum += math::boxminus(P[m].q_WR.normalized(), q_interp);
      ++count;
    }
    if (count >= 3) {
      ps.push_back(p_sum / count);
      qs.push_back(math::boxplus(q_interp, th_sum / count));
    } else {
      ps.push_back((1.0 - a) * P[j].p_WR + a * P[j1].p_WR);
      qs.push_back(q_interp);
    }
  }
  // Make the spline interpolate the (box-filtered) samples at the knots: the cubic B-spline passes through
  // (c_{k-1} + 4 c_k + c_{k+1}) / 6, so correct the control poses by the residual a few times (a Jacobi-like
  // fixed-point iteration; the residual shrinks by >= 1/3 per pass).
  const std::vector<Quaterniond> q_target = qs;
  const std::vector<Vector3d> p_target = ps;
  for (int pass = 0; pass < 12; ++pass) {
    const SplineTrajectory current(t0, dt, qs, ps, rec.source);
    std::vector<Quaterniond> q_next = qs;
    std::vector<Vector3d> p_next = ps;
    for (std::size_t k = 1; k + 1 < n; ++k) {
      const KinematicState s = current.at(t0 + static_cast<TimeNs>(k) * dt);
      p_next[k] += p_target[k] - s.p_WR;
      q_next[k] = math::boxplus(qs[k], math::boxminus(q_target[k], s.q_WR));
    }
    qs = std::move(q_next);
    ps = std::move(p_next);
  }
  return SplineTrajectory(t0, dt, std::move(qs), std::move(ps), "follow:" + rec.source);
}

KinematicState SplineTrajectory::at(TimeNs t_ns) const {
  const TimeNs tc = std::clamp(t_ns, t_begin(), t_end());
  const TimeNs rel = tc - t0_ - dt_;
  auto seg = static_cast<std::size_t>(rel / dt_);
  seg = std::min(seg, q_.size() - 4);
  const double u = static_cast<double>(rel - static_cast<TimeNs>(seg) * dt_) / static_cast<double>(dt_);
  const double dts = to_seconds(dt_);
  Vector3d b, b1, b2;
  cumulative_basis(u, b, b1, b2);
  b1 /= dts;
  b2 /= dts * dts;

  KinematicState s;
  s.t = t_ns;
  s.p_WR = p_[seg];
  Quaterniond q = q_[seg];
  Vector3d w = Vector3d::Zero(), dw = Vector3d::Zero();
  for (int j = 1; j <= 3; ++j) {
    const std::size_t k = seg + static_cast<std::size_t>(j);
    const Vector3d dp = p_[k] - p_[k - 1];
    s.p_WR += b[j - 1] * dp;
    s.v_WR += b1[j - 1] * dp;
    s.a_WR += b2[j - 1] * dp;
    // R_j = R_{j-1} A_j with A_j = Exp(b_j Ω_k): w_j = A_jᵀ w_{j-1} + b'_j Ω_k,
    // dw_j = A_jᵀ dw_{j-1} − (b'_j Ω_k) × (A_jᵀ w_{j-1}) + b''_j Ω_k.
    const Quaterniond A = math::exp_so3(b[j - 1] * omega_[k]);
    const Matrix3d At = A.toRotationMatrix().transpose();
    const Vector3d At_w = At * w;
    const Vector3d rate = b1[j - 1] * omega_[k];
    dw = At * dw - rate.cross(At_w) + b2[j - 1] * omega_[k];
    w = At_w + rate;
    q = q * A;
  }
  s.q_WR = q.normalized();
  s.w_R = w;
  s.dw_R = dw;
  if (tc != t_ns) {
    s.v_WR.setZero();
    s.a_WR.setZero();
    s.w_R.setZero();
    s.dw_R.setZero();
  }
  return s;
}

namespace {

Wave random_wave(Rng& rng, double amplitude, double f_lo, double f_hi, double t_on, double t_off, double ramp) {
  Wave w;
  w.amplitude = amplitude * randu(rng, 0.7, 1.0);
  w.freq_hz = randu(rng, f_lo, f_hi);
  w.phase_rad = randu(rng, 0.0, kTwoPi);
  w.t_on_s = t_on;
  w.t_off_s = t_off;
  w.ramp_s = ramp;
  return w;
}

}  // namespace

std::unique_ptr<ContinuousTrajectory> make_handheld(std::uint64_t seed, const Vector3d& center, double duration_s,
                                                    TimeNs t_begin) {
  Rng rng(seed ^ 0x68616e6468656c64ULL);  // "handheld": this stream is only for the trajectory's shape
  WaveTrajectoryParams p;
  p.t_begin = t_begin;
  p.duration_s = duration_s;
  p.name = fmt::format("handheld(seed={})", seed);
  p.warmup_s = 2.0;  // start at rest
  const double on = -1e9, off = 1e9, ramp = 0.0;  // waves always on
  // Walk around the room centre (about ±1 m horizontally, ±0.2 m vertically), slow and smooth.
  const std::array<double, 3> amp{0.8, 0.8, 0.15};
  for (int i = 0; i < 3; ++i) {
    p.position[i].offset = center[i];
    p.position[i].waves = {random_wave(rng, amp[i], 0.03, 0.08, on, off, ramp),
                           random_wave(rng, 0.3 * amp[i], 0.1, 0.25, on, off, ramp),
                           random_wave(rng, 0.01 * amp[i] + 0.004, 0.6, 1.2, on, off, ramp)};
  }
  // Look around: a slow yaw sweep over most of the room, some tilt, small roll, hand tremor on top.
  p.yaw.offset = randu(rng, -std::numbers::pi, std::numbers::pi);
  p.yaw.waves = {random_wave(rng, 1.6, 0.02, 0.05, on, off, ramp), random_wave(rng, 0.3, 0.1, 0.2, on, off, ramp),
                 random_wave(rng, 0.01, 0.8, 1.5, on, off, ramp)};
  p.pitch.waves = {random_wave(rng, 0.2, 0.04, 0.1, on, off, ramp), random_wave(rng, 0.05, 0.2, 0.4, on, off, ramp),
                   random_wave(rng, 0.008, 0.8, 1.5, on, off, ramp)};
  p.roll.waves = {random_wave(rng, 0.12, 0.03, 0.08, on, off, ramp), random_wave(rng, 0.03, 0.2, 0.4, on, off, ramp)};
  return std::make_unique<WaveTrajectory>(std::move(p));
}

GroundTrajectory::GroundTrajectory(GroundTrajectoryParams params) : params_(std::move(params)) {
  const GroundTrajectoryParams& p = params_;
  if (!(p.a > 0.0 && p.b > 0.0 && std::isfinite(p.a) && std::isfinite(p.b)))
    throw ConfigError(fmt::format("ground trajectory: semi-axes must be positive (got {}, {})", p.a, p.b));
  if (!(p.rest_s >= 0.0 && p.ramp_s > 0.0 && std::isfinite(p.rate)))
    throw ConfigError("ground trajectory: rest_s >= 0, ramp_s > 0 and a finite rate are required");
}

KinematicState GroundTrajectory::at(TimeNs t_ns) const {
  const GroundTrajectoryParams& p = params_;
  const double t = std::clamp(to_seconds(t_ns - p.t_begin), 0.0, p.duration_s);
  // φ̇ = rate · smootherstep(τ), τ = (t − rest) / ramp; φ is its integral (τ⁶ − 3τ⁵ + 2.5τ⁴ over the ramp).
  double phi = p.phase, dphi = 0.0, ddphi = 0.0;
  if (t > p.rest_s) {
    const double tau = std::min((t - p.rest_s) / p.ramp_s, 1.0);
    double sv = 0.0, s1 = 0.0, s2 = 0.0;
    smootherstep(tau, sv, s1, s2);
    const double integral = p.ramp_s * (std::pow(tau, 6) - 3.0 * std::pow(tau, 5) + 2.5 * std::pow(tau, 4));
    phi += p.rate * (integral + std::max(0.0, t - p.rest_s - p.ramp_s));
    dphi = p.rate * sv;
    ddphi = tau < 1.0 ? p.rate * s1 / p.ramp_s : 0.0;
  }
  const double c = std::cos(phi), s = std::sin(phi);
  KinematicState k;
  k.t = t_ns;
  k.p_WR = p.center + Vector3d(p.a * c, p.b * s, 0.0);
  const Vector3d d1(-p.a * s, p.b * c, 0.0);   // ∂p/∂φ
  const Vector3d d2(-p.a * c, -p.b * s, 0.0);  // ∂²p/∂φ²
  k.v_WR = dphi * d1;
  k.a_WR = ddphi * d1 + dphi * dphi * d2;
  // Heading along ∂p/∂φ times the direction of travel (at rest: the direction it will drive).
  const double dir = p.rate >= 0.0 ? 1.0 : -1.0;
  const double psi = std::atan2(dir * d1.y(), dir * d1.x());
  // dψ/dφ = a b / D, D = a² sin²φ + b² cos²φ; d²ψ/dφ² = −a b (a² − b²) sin 2φ / D².
  const double D = p.a * p.a * s * s + p.b * p.b * c * c;
  const double g1 = p.a * p.b / D;
  const double g2 = -p.a * p.b * (p.a * p.a - p.b * p.b) * std::sin(2.0 * phi) / (D * D);
  const double dpsi = g1 * dphi;
  const double ddpsi = g2 * dphi * dphi + g1 * ddphi;
  k.q_WR = Quaterniond(Eigen::AngleAxisd(psi, Vector3d::UnitZ()).toRotationMatrix() * WaveTrajectory::base_rotation())
               .normalized();
  // R's x axis is W's z: a yaw rate is a body rate about x.
  k.w_R = Vector3d(dpsi, 0.0, 0.0);
  k.dw_R = Vector3d(ddpsi, 0.0, 0.0);
  return k;
}

std::unique_ptr<ContinuousTrajectory> make_ground(std::uint64_t seed, const Vector3d& center,
                                                  const Eigen::Vector2d& room_size, double speed_mps,
                                                  double duration_s, TimeNs t_begin) {
  Rng rng(seed ^ 0x67726f756e64ULL);  // "ground"
  GroundTrajectoryParams p;
  p.center = center;
  p.a = 0.3 * room_size.x();
  p.b = 0.3 * room_size.y();
  p.phase = randu(rng, -std::numbers::pi, std::numbers::pi);
  const double direction = randu(rng, 0.0, 1.0) < 0.5 ? -1.0 : 1.0;
  p.rate = direction * speed_mps / (0.5 * (p.a + p.b));
  p.t_begin = t_begin;
  p.duration_s = duration_s;
  p.name = fmt::format("ground(seed={})", seed);
  return std::make_unique<GroundTrajectory>(std::move(p));
}

std::unique_ptr<ContinuousTrajectory> make_high_dynamic(std::uint64_t seed, const Vector3d& center,
                                                        double duration_s, TimeNs t_begin) {
  Rng rng(seed ^ 0x6869676864796eULL);  // "highdyn"
  WaveTrajectoryParams p;
  p.t_begin = t_begin;
  p.duration_s = duration_s;
  p.name = fmt::format("high-dynamic(seed={})", seed);
  for (int i = 0; i < 3; ++i) p.position[i].offset = center[i];
  p.yaw.offset = randu(rng, -std::numbers::pi, std::numbers::pi);
  // Phase 1 (1 s .. 25 s): every DoF excited alone for 4 s, moderate dynamics (0.25 m at 0.6 Hz ~ 3.5 m/s²;
  // 0.35 rad at 0.6 Hz ~ 75 deg/s).
  WaveChannel* order[6] = {&p.position[0], &p.position[1], &p.position[2], &p.roll, &p.pitch, &p.yaw};
  const double amp[6] = {0.25, 0.25, 0.2, 0.35, 0.3, 0.5};
  for (int k = 0; k < 6; ++k) {
    const double t_on = 1.0 + 4.0 * k;
    order[k]->waves.push_back(random_wave(rng, amp[k] / 0.85, 0.55, 0.65, t_on, t_on + 4.0, 0.8));
  }
  // Phase 2 (26 s ..): lateral (y) shaking and yaw swings together, growing to the paper's extremes. Yaw
  // 0.85 rad at 1.4 Hz: rate 7.5 rad/s = 428 deg/s, angular acceleration 66 rad/s² = 3780 deg/s²;
  // y 0.2 m at 2 Hz: 31.6 m/s² = 3.2 g. Amplitudes are not randomized here (only phases) so the extremes hold.
  const double t2 = 26.0;
  auto fixed_wave = [&rng](double a, double f, double t_on, double t_off, double ramp) {
    return Wave{a, f, randu(rng, 0.0, kTwoPi), t_on, t_off, ramp};
  };
  p.yaw.waves.push_back(fixed_wave(0.55, 1.2, t2, t2 + 6.0, 1.0));        // ~240 deg/s
  p.yaw.waves.push_back(fixed_wave(0.85, 1.4, t2 + 5.0, 1e9, 1.0));       // > 400 deg/s
  p.position[1].waves.push_back(fixed_wave(0.1, 1.5, t2, t2 + 6.0, 1.0)); // ~0.9 g
  p.position[1].waves.push_back(fixed_wave(0.2, 2.0, t2 + 5.0, 1e9, 1.0));
  p.pitch.waves.push_back(fixed_wave(0.1, 0.7, t2, 1e9, 1.0));  // keep some excitation on the other axes
  p.position[2].waves.push_back(fixed_wave(0.05, 0.9, t2, 1e9, 1.0));
  return std::make_unique<WaveTrajectory>(std::move(p));
}

RecordedTrajectory::RecordedTrajectory(const Trajectory& rec) : name_("recorded:" + rec.source) {
  const auto& P = rec.poses;
  if (P.size() < 2) throw DataError(fmt::format("{}: a recorded trajectory needs at least 2 poses, has {}", rec.source, P.size()));
  for (std::size_t i = 0; i < P.size(); ++i) {
    if (i > 0 && P[i].t <= P[i - 1].t)
      throw DataError(fmt::format("{}: timestamps not increasing at pose {} (t = {} ns)", rec.source, i, P[i].t));
    if (!P[i].p_WR.allFinite() || !P[i].q_WR.coeffs().allFinite() || P[i].q_WR.norm() < 0.5)
      throw DataError(fmt::format("{}: pose {} (t = {} ns) is not a finite pose with a unit quaternion", rec.source, i,
                                  P[i].t));
    t_.push_back(P[i].t);
    Quaterniond q = P[i].q_WR.normalized();
    if (i > 0 && q.dot(q_.back()) < 0.0) q.coeffs() = -q.coeffs();  // continuous signs for the slerp
    q_.push_back(q);
    p_.push_back(P[i].p_WR);
  }
  for (std::size_t i = 0; i < P.size(); ++i) {
    if (P[i].v_WR) {
      v_.push_back(*P[i].v_WR);
      continue;
    }
    const std::size_t a = i == 0 ? 0 : i - 1, b = std::min(i + 1, P.size() - 1);
    v_.push_back((p_[b] - p_[a]) / to_seconds(t_[b] - t_[a]));
  }
}

KinematicState RecordedTrajectory::at(TimeNs t) const {
  t = std::clamp(t, t_.front(), t_.back());
  // Interval [k, k+1] holding t (the last interval for t = t_end).
  const auto it = std::upper_bound(t_.begin(), t_.end(), t);
  const std::size_t k = std::min(static_cast<std::size_t>(std::max<std::ptrdiff_t>(it - t_.begin() - 1, 0)), t_.size() - 2);
  const double h = to_seconds(t_[k + 1] - t_[k]);
  const double s = to_seconds(t - t_[k]) / h;
  KinematicState st;
  st.t = t;
  if (t == t_[k]) {
    st.p_WR = p_[k];
    st.q_WR = q_[k];
  } else if (t == t_[k + 1]) {
    st.p_WR = p_[k + 1];
    st.q_WR = q_[k + 1];
  } else {
    const double s2 = s * s, s3 = s2 * s;
    st.p_WR = (2 * s3 - 3 * s2 + 1) * p_[k] + (s3 - 2 * s2 + s) * h * v_[k] + (-2 * s3 + 3 * s2) * p_[k + 1] +
              (s3 - s2) * h * v_[k + 1];
    st.q_WR = q_[k] * math::exp_so3(s * math::boxminus(q_[k + 1], q_[k]));
  }
  // Derivatives of the Hermite basis: d/dt = (1/h) d/ds.
  const double s2 = s * s;
  st.v_WR = ((6 * s2 - 6 * s) * p_[k] + (3 * s2 - 4 * s + 1) * h * v_[k] + (-6 * s2 + 6 * s) * p_[k + 1] +
             (3 * s2 - 2 * s) * h * v_[k + 1]) / h;
  st.a_WR = ((12 * s - 6) * p_[k] + (6 * s - 4) * h * v_[k] + (-12 * s + 6) * p_[k + 1] + (6 * s - 2) * h * v_[k + 1]) /
            (h * h);
  st.w_R = math::boxminus(q_[k + 1], q_[k]) / h;
  st.dw_R.setZero();
  return st;
}

std::unique_ptr<ContinuousTrajectory> make_follow(const std::string& path, double knot_dt_s) {
  if (!(knot_dt_s > 0.0)) throw ConfigError(fmt::format("follow:{}: knot spacing {} s must be > 0", path, knot_dt_s));
  const Trajectory rec = io::read_trajectory(path);
  return std::make_unique<SplineTrajectory>(SplineTrajectory::from_recorded(rec, from_seconds(knot_dt_s)));
}

}  // namespace rtslam::sim
