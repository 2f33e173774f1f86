#pragma once
// Chi-square distribution: CDF through the regularized incomplete gamma function, quantiles by a safeguarded
// Newton iteration on that CDF (accurate to ~1e-12 relative), and the two-sided NEES consistency bands.
//
//   P(a, x) = γ(a, x) / Γ(a)  (regularized lower incomplete gamma), chi2_cdf(x; k) = P(k/2, x/2).
//   Series for x < a + 1, Lentz continued fraction for Q = 1 − P otherwise (Numerical Recipes §6.2 forms).
#include <utility>

namespace rtslam::eval {

/// Regularized lower incomplete gamma P(a, x), a > 0, x >= 0. Throws DataError on a bad argument.
double gamma_p(double a, double x);

/// Regularized upper incomplete gamma Q(a, x) = 1 − P(a, x), computed directly (no cancellation in the tail).
double gamma_q(double a, double x);

/// Chi-square CDF with `dof` > 0 degrees of freedom (dof may be fractional).
double chi2_cdf(double x, double dof);

/// Chi-square quantile: the x with chi2_cdf(x, dof) = p, for 0 < p < 1.
double chi2_quantile(double p, double dof);

/// Two-sided band of the average NEES of `n_runs` independent runs of a `dim`-dimensional error:
/// N·ε̄ ~ χ²(dim·N), so the band is [χ²_{α/2}(dim·N)/N, χ²_{1−α/2}(dim·N)/N] with α = 1 − confidence.
/// For dim = 6, N = 1, confidence 0.99: [0.676, 18.55].
std::pair<double, double> nees_band(int dim, int n_runs, double confidence = 0.99);

}  // namespace rtslam::eval
