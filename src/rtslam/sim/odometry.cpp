#include "rtslam/sim/odometry.hpp"

#include <cmath>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/yaml.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::sim {

void OdometrySynthOptions::read(YamlMap& m) {
  enabled = true;
  m.get("enabled", enabled);
  m.get("rate_hz", rate_hz);
  m.get("sigma_p", noise.sigma_p);
  m.get("sigma_theta", noise.sigma_theta);
  m.get("k_p", noise.k_p);
  m.get("k_theta", noise.k_theta);
  m.get("noise", noise_enabled);
}

void OdometrySynthOptions::validate(const std::string& where) const {
  require_bound(rate_hz > 0.0 && rate_hz <= 1000.0, where, "rate_hz", rate_hz, "in (0, 1000]");
  const auto check = [&](double v, const char* key) { require_bound(v >= 0.0 && v <= 10.0, where, key, v, "in [0, 10]"); };
  check(noise.sigma_p, "sigma_p");
  check(noise.sigma_theta, "sigma_theta");
  check(noise.k_p, "k_p");
  check(noise.k_theta, "k_theta");
}

std::vector<SynthOdometry> synthesize_odometry(const ContinuousTrajectory& trajectory, TimeNs t0, TimeNs t1,
                                               const OdometrySynthOptions& options, Rng rng) {
  options.validate("odometry");
  std::vector<SynthOdometry> out;
  const double period_ns = 1e9 / options.rate_hz;
  KinematicState a = trajectory.at(t0);
  TimeNs t_prev = t0;
  for (std::size_t k = 1;; ++k) {
    const TimeNs t = t0 + static_cast<TimeNs>(std::llround(static_cast<double>(k) * period_ns));
    if (t > t1) break;
    const KinematicState b = trajectory.at(t);
    SynthOdometry o;
    o.t_from = t_prev;
    o.t = t;
    o.dp = a.q_WR.conjugate() * (b.p_WR - a.p_WR);
    o.dtheta = math::log_so3((a.q_WR.conjugate() * b.q_WR).normalized());
    if (options.noise_enabled) {
      const models::Matrix6d U =
          models::odometry_input_covariance({o.dp, o.dtheta, to_seconds(t - t_prev)}, options.noise);
      o.dp += randn_vec<3>(rng, std::sqrt(U(0, 0)));
      o.dtheta += randn_vec<3>(rng, std::sqrt(U(3, 3)));
    }
    out.push_back(o);
    a = b;
    t_prev = t;
  }
  return out;
}

}  // namespace rtslam::sim
