// The inertial model on real data (issue "Inertial/visual SLAM", acceptance): the real EuRoC V1_01 IMU (ADIS16448,
// 200 Hz, the whole flight) propagated alone by the midpoint model from the ground-truth state (p, q, v and both
// biases of the state CSV, gravity 9.81 m/s² along −z of W) over 1 s windows of the moving part of the flight:
// median position error <= 3 cm, p90 <= 5 cm. Windows start every 0.5 s at a ground-truth sample; the part where the
// MAV moves is where the ground-truth speed exceeds 0.1 m/s at the window start.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <variant>
#include <vector>

#include "rtslam/io/dataset.hpp"
#include "rtslam/math/rotation.hpp"
#include "rtslam/models/robots/inertial.hpp"

namespace rtslam::models {
namespace {

const std::string kEuroc = RTSLAM_SOURCE_DIR "/../shared/datasets/euroc-v101-static";

struct ImuRecord {
  TimeNs t;
  ImuMeasurement m;
};

std::vector<ImuRecord> read_imu(io::Source& source) {
  std::vector<ImuRecord> out;
  while (auto m = source.next()) {
    if (const auto* s = std::get_if<io::ImuSample>(&*m)) out.push_back({s->t, ImuMeasurement{s->accel, s->gyro}});
  }
  return out;
}

// Linear interpolation of the reading at t inside [a, b] (the model's "instantaneous values at their timestamps").
ImuMeasurement reading_at(const ImuRecord& a, const ImuRecord& b, TimeNs t) {
  const double s = static_cast<double>(t - a.t) / static_cast<double>(b.t - a.t);
  return ImuMeasurement{a.m.accel + s * (b.m.accel - a.m.accel), a.m.gyro + s * (b.m.gyro - a.m.gyro)};
}

// Propagates x from t0 to t1 with the samples (t0 and t1 inside the recorded span), exactly to both ends.
Vector19d propagate(const std::vector<ImuRecord>& imu, Vector19d x, TimeNs t0, TimeNs t1, const InertialParams& p) {
  auto it = std::upper_bound(imu.begin(), imu.end(), t0, [](TimeNs t, const ImuRecord& r) { return t < r.t; });
  TimeNs t = t0;
  ImuMeasurement m0 = reading_at(*(it - 1), *it, t0);
  while (t < t1) {
    const TimeNs t_next = std::min(it->t, t1);
    const ImuMeasurement m1 = t_next == it->t ? it->m : reading_at(*(it - 1), *it, t_next);
    inertial_predict(x, m0, m1, to_seconds(t_next - t), p, x);
    m0 = m1;
    t = t_next;
    if (t == it->t) ++it;
  }
  return x;
}

TEST(InertialEuroc, RealImuAlonePropagatesOneSecondWindowsWithinCentimetres) {
  if (!std::filesystem::exists(kEuroc)) GTEST_SKIP() << "dataset " << kEuroc << " not found";
  io::DatasetOptions opt;
  opt.cameras = {};  // IMU only
  io::Dataset ds = io::open_dataset("euroc:" + kEuroc, opt);
  ASSERT_TRUE(ds.ground_truth.has_value());
  const std::vector<ImuRecord> imu = read_imu(*ds.source);
  ASSERT_GT(imu.size(), 20000u);
  const auto& gt = ds.ground_truth->poses;

  const InertialParams params;
  const TimeNs window = from_seconds(1.0);
  std::vector<double> errors;
  TimeNs next_start = gt.front().t;
  for (std::size_t k = 0; k < gt.size(); ++k) {
    const StampedPose& g0 = gt[k];
    if (g0.t < next_start || !g0.v_WR || !g0.accel_bias || !g0.gyro_bias) continue;
    if (g0.t <= imu.front().t || g0.t + window >= imu.back().t) continue;
    if (g0.v_WR->norm() < 0.1) continue;  // the moving part of the flight
    // The ground-truth sample one window later (same 20 Hz clock).
    const auto end = std::lower_bound(gt.begin() + static_cast<std::ptrdiff_t>(k), gt.end(), g0.t + window,
                                      [](const StampedPose& s, TimeNs t) { return s.t < t; });
    if (end == gt.end() || end->t - g0.t > window + from_seconds(0.01)) continue;
    next_start = g0.t + from_seconds(0.5);
    Vector19d x;
    x << g0.p_WR, math::quat_to_wxyz(g0.q_WR), *g0.v_WR, *g0.accel_bias, *g0.gyro_bias, 0.0, 0.0, -9.81;
    const Vector19d x1 = propagate(imu, x, g0.t, end->t, params);
    errors.push_back((x1.head<3>() - end->p_WR).norm());
  }
  ASSERT_GE(errors.size(), 150u) << "too few moving windows";
  std::sort(errors.begin(), errors.end());
  const double median = errors[errors.size() / 2];
  const double p90 = errors[static_cast<std::size_t>(0.9 * static_cast<double>(errors.size()))];
  std::printf("%zu windows of 1 s: position error median %.4f m, p90 %.4f m, max %.4f m\n", errors.size(), median,
              p90, errors.back());
  EXPECT_LE(median, 0.03);
  EXPECT_LE(p90, 0.05);
}

}  // namespace
}  // namespace rtslam::models
