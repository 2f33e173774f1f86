#pragma once
// One seeded generator per run, passed explicitly; no global random state.
#include <cstdint>
#include <random>

#include <Eigen/Core>

namespace rtslam {

using Rng = std::mt19937_64;

/// A standard normal sample.
inline double randn(Rng& rng) { return std::normal_distribution<double>(0.0, 1.0)(rng); }

/// A uniform sample in [lo, hi).
inline double randu(Rng& rng, double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); }

/// A vector of independent N(0, sigma^2) samples.
template <int N>
Eigen::Matrix<double, N, 1> randn_vec(Rng& rng, double sigma = 1.0) {
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) v[i] = sigma * randn(rng);
  return v;
}

}  // namespace rtslam
