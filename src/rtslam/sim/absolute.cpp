#include "rtslam/sim/absolute.hpp"

#include <cmath>

#include "rtslam/core/random.hpp"
#include "rtslam/math/rotation.hpp"

namespace rtslam::sim {

namespace {

constexpr double kDeg = M_PI / 180.0;

template <class F>
void at_rate(TimeNs t0, TimeNs t1, double rate_hz, F&& f) {
  const double period_ns = 1e9 / rate_hz;
  for (std::size_t k = 0;; ++k) {
    const TimeNs t = t0 + static_cast<TimeNs>(std::llround(static_cast<double>(k) * period_ns));
    if (t > t1) break;
    f(t);
  }
}

}  // namespace

void AbsoluteSimOptions::read(YamlMap& m, bool pose) {
  m.get("enabled", enabled);
  m.get("rate_hz", rate_hz);
  m.get("sigma", sigma_m);
  if (m.has("lever_arm")) m.get_matrix("lever_arm", lever_arm);
  if (pose) {
    m.get("sigma_deg", sigma_deg);
    if (m.has("rotation_deg")) m.get_matrix("rotation_deg", rotation_deg);
  }
}

void AbsoluteSimOptions::validate(const std::string& w) const {
  require_bound(rate_hz > 0.0 && rate_hz <= 1000.0, w, "rate_hz", rate_hz, "in (0, 1000] Hz");
  require_bound(sigma_m >= 0.0 && sigma_m <= 1e4, w, "sigma", sigma_m, "in [0, 1e4] m");
  require_bound(sigma_deg >= 0.0 && sigma_deg <= 180.0, w, "sigma_deg", sigma_deg, "in [0, 180] deg");
  for (int i = 0; i < 3; ++i) {
    require_bound(std::abs(lever_arm[i]) <= 100.0, w, "lever_arm", lever_arm[i], "in [-100, 100] m per axis");
    require_bound(std::abs(rotation_deg[i]) <= 360.0, w, "rotation_deg", rotation_deg[i], "in [-360, 360] deg");
  }
}

std::vector<io::PositionSample> make_position_fixes(const ContinuousTrajectory& traj, TimeNs t0, TimeNs t1,
                                                    const AbsoluteSimOptions& o, std::uint64_t seed) {
  std::vector<io::PositionSample> out;
  Rng rng(seed);
  at_rate(t0, t1, o.rate_hz, [&](TimeNs t) {
    const KinematicState s = traj.at(t);
    out.push_back({t, s.p_WR + s.q_WR * o.lever_arm + randn_vec<3>(rng, o.sigma_m)});
  });
  return out;
}

std::vector<io::PoseSample> make_pose_fixes(const ContinuousTrajectory& traj, TimeNs t0, TimeNs t1,
                                            const AbsoluteSimOptions& o, std::uint64_t seed) {
  std::vector<io::PoseSample> out;
  Rng rng(seed);
  const Eigen::Quaterniond q_RM = math::exp_so3(o.rotation_deg * kDeg);
  at_rate(t0, t1, o.rate_hz, [&](TimeNs t) {
    const KinematicState s = traj.at(t);
    io::PoseSample f;
    f.t = t;
    f.p = s.p_WR + s.q_WR * o.lever_arm + randn_vec<3>(rng, o.sigma_m);
    f.q = (s.q_WR * q_RM * math::exp_so3(randn_vec<3>(rng, o.sigma_deg * kDeg))).normalized();
    out.push_back(f);
  });
  return out;
}

}  // namespace rtslam::sim
