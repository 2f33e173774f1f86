// Chi-square CDF/quantiles against tabulated values and exact closed forms; NEES bands of MATH.md.
#include <cmath>

#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"
#include "rtslam/eval/chi2.hpp"

using namespace rtslam::eval;

TEST(Chi2, QuantilesMatchTabulatedValues) {
  // Standard table values (NIST/SEMATECH e-Handbook 1.3.6.7.4), given to 3 decimals.
  struct Row { double p, dof, x; };
  const Row rows[] = {
      {0.995, 1, 7.879},   {0.99, 2, 9.210},    {0.01, 2, 0.020},   {0.995, 6, 18.548},  {0.005, 6, 0.676},
      {0.975, 10, 20.483}, {0.025, 10, 3.247},  {0.995, 10, 25.188}, {0.005, 10, 2.156}, {0.95, 30, 43.773},
      {0.05, 30, 18.493},  {0.995, 100, 140.169}, {0.005, 100, 67.328}, {0.90, 50, 63.167}, {0.10, 50, 37.689},
  };
  for (const auto& r : rows) {
    EXPECT_NEAR(chi2_quantile(r.p, r.dof), r.x, 6e-4) << "p = " << r.p << ", dof = " << r.dof;
  }
}

TEST(Chi2, TwoDofQuantileEqualsClosedForm) {
  // χ²(2) is exponential with mean 2: F(x) = 1 − exp(−x/2), x_p = −2 ln(1 − p).
  for (double p : {1e-6, 0.005, 0.1, 0.5, 0.9, 0.995, 1 - 1e-9}) {
    const double exact = -2.0 * std::log1p(-p);
    EXPECT_NEAR(chi2_quantile(p, 2.0), exact, 1e-10 * std::max(1.0, exact)) << p;
    EXPECT_NEAR(chi2_cdf(exact, 2.0), p, 1e-13) << p;
  }
}

TEST(Chi2, OneDofCdfEqualsErf) {
  // χ²(1): F(x) = erf(sqrt(x/2)).
  for (double x : {1e-4, 0.3, 1.0, 3.84, 6.63, 20.0, 60.0}) {
    EXPECT_NEAR(chi2_cdf(x, 1.0), std::erf(std::sqrt(0.5 * x)), 1e-13) << x;
  }
}

TEST(Chi2, QuantileInvertsCdfForLargeDof) {
  for (double dof : {6.0, 60.0, 600.0, 6000.0}) {
    for (double p : {0.005, 0.5, 0.995}) {
      EXPECT_NEAR(chi2_cdf(chi2_quantile(p, dof), dof), p, 1e-11) << dof << " " << p;
    }
  }
}

TEST(Chi2, NeesBandForOneRunOfSixDofMatchesMathMd) {
  const auto [lo, hi] = nees_band(6, 1, 0.99);
  EXPECT_NEAR(lo, 0.676, 5e-4);
  EXPECT_NEAR(hi, 18.548, 5e-4);
}

TEST(Chi2, NeesBandShrinksTowardsDimensionWithManyRuns) {
  // 100 runs: [χ²_0.005(600)/100, χ²_0.995(600)/100]; the band must contain 6 and be much narrower than one run's.
  const auto [lo, hi] = nees_band(6, 100, 0.99);
  EXPECT_LT(lo, 6.0);
  EXPECT_GT(hi, 6.0);
  EXPECT_NEAR(lo * 100, chi2_quantile(0.005, 600), 1e-9);
  // Normal approximation of χ²(600): 600 ± 2.5758·sqrt(1200) → [5.108, 6.892]; skewness shifts it slightly up.
  EXPECT_NEAR(lo, 5.14, 0.05);
  EXPECT_NEAR(hi, 6.92, 0.05);
}

TEST(Chi2, BadArgumentsThrow) {
  EXPECT_THROW(chi2_quantile(0.0, 6), rtslam::DataError);
  EXPECT_THROW(chi2_quantile(1.0, 6), rtslam::DataError);
  EXPECT_THROW(chi2_quantile(0.5, 0), rtslam::DataError);
  EXPECT_THROW(nees_band(6, 0), rtslam::DataError);
  EXPECT_THROW(gamma_p(-1.0, 1.0), rtslam::DataError);
}
