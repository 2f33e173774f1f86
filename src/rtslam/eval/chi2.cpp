#include "rtslam/eval/chi2.hpp"

#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "rtslam/core/error.hpp"

namespace rtslam::eval {
namespace {

constexpr int kMaxIterations = 100000;
constexpr double kEps = 1e-16;
constexpr double kTiny = 1e-300;

// log of the common prefactor x^a e^{-x} / Γ(a).
double log_prefactor(double a, double x) { return a * std::log(x) - x - std::lgamma(a); }

// P(a, x) by its power series, valid (fast) for x < a + 1.
double gamma_p_series(double a, double x) {
  double ap = a;
  double term = 1.0 / a;
  double sum = term;
  for (int n = 0; n < kMaxIterations; ++n) {
    ap += 1.0;
    term *= x / ap;
    sum += term;
    if (std::abs(term) < std::abs(sum) * kEps) break;
  }
  return sum * std::exp(log_prefactor(a, x));
}

// Q(a, x) by its continued fraction (modified Lentz), valid (fast) for x >= a + 1.
double gamma_q_fraction(double a, double x) {
  double b = x + 1.0 - a;
  double c = 1.0 / kTiny;
  double d = 1.0 / b;
  double h = d;
  for (int i = 1; i < kMaxIterations; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < kEps) break;
  }
  return std::exp(log_prefactor(a, x)) * h;
}

void check_args(double a, double x) {
  if (!(a > 0.0) || !(x >= 0.0) || !std::isfinite(a))
    throw DataError(fmt::format("incomplete gamma: need a > 0 and x >= 0, got a = {}, x = {}", a, x));
}

}  // namespace

double gamma_p(double a, double x) {
  check_args(a, x);
  if (x == 0.0) return 0.0;
  if (std::isinf(x)) return 1.0;
  return x < a + 1.0 ? gamma_p_series(a, x) : 1.0 - gamma_q_fraction(a, x);
}

double gamma_q(double a, double x) {
  check_args(a, x);
  if (x == 0.0) return 1.0;
  if (std::isinf(x)) return 0.0;
  return x < a + 1.0 ? 1.0 - gamma_p_series(a, x) : gamma_q_fraction(a, x);
}

double chi2_cdf(double x, double dof) {
  if (!(dof > 0.0)) throw DataError(fmt::format("chi2_cdf: degrees of freedom must be > 0, got {}", dof));
  if (x <= 0.0) return 0.0;
  return gamma_p(0.5 * dof, 0.5 * x);
}

double chi2_quantile(double p, double dof) {
  if (!(dof > 0.0)) throw DataError(fmt::format("chi2_quantile: degrees of freedom must be > 0, got {}", dof));
  if (!(p > 0.0 && p < 1.0)) throw DataError(fmt::format("chi2_quantile: probability must be in (0, 1), got {}", p));
  // Bracket the root of f(x) = cdf(x) − p, then Newton steps that fall back to bisection when they leave the bracket.
  // In the upper tail the residual is computed from Q to keep relative accuracy.
  const bool upper = p > 0.5;
  const double q = 1.0 - p;
  auto residual = [&](double x) {
    return upper ? q - gamma_q(0.5 * dof, 0.5 * x) : gamma_p(0.5 * dof, 0.5 * x) - p;
  };
  double lo = 0.0;
  double hi = std::max(1.0, dof);
  while (residual(hi) < 0.0) {
    lo = hi;
    hi *= 2.0;
    if (hi > 1e12) throw DataError(fmt::format("chi2_quantile: no bracket for p = {}, dof = {}", p, dof));
  }
  double x = 0.5 * (lo + hi);
  const double k2 = 0.5 * dof;
  for (int it = 0; it < 500; ++it) {
    const double f = residual(x);
    if (f == 0.0) return x;
    if (f < 0.0) lo = x; else hi = x;
    // pdf(x) = x^{k/2−1} e^{−x/2} / (2^{k/2} Γ(k/2))
    const double log_pdf = (k2 - 1.0) * std::log(x) - 0.5 * x - k2 * std::log(2.0) - std::lgamma(k2);
    const double pdf = std::exp(log_pdf);
    double next = pdf > 0.0 && std::isfinite(pdf) ? x - f / pdf : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - x) <= 1e-14 * std::max(1.0, x) || hi - lo <= 1e-15 * std::max(1.0, x)) return next;
    x = next;
  }
  return x;
}

std::pair<double, double> nees_band(int dim, int n_runs, double confidence) {
  if (dim <= 0 || n_runs <= 0)
    throw DataError(fmt::format("nees_band: need dim > 0 and n_runs > 0, got dim = {}, n_runs = {}", dim, n_runs));
  if (!(confidence > 0.0 && confidence < 1.0))
    throw DataError(fmt::format("nees_band: confidence must be in (0, 1), got {}", confidence));
  const double alpha = 1.0 - confidence;
  const double dof = static_cast<double>(dim) * n_runs;
  return {chi2_quantile(0.5 * alpha, dof) / n_runs, chi2_quantile(1.0 - 0.5 * alpha, dof) / n_runs};
}

}  // namespace rtslam::eval
