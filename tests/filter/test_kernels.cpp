// The correction kernels (filter/kernels.hpp) on active rows with holes: against dense references, and the generic
// and AVX2 versions bit-identical (the AVX2 comparisons are skipped on a CPU without it).
#include "rtslam/filter/kernels.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <gtest/gtest.h>

#include "rtslam/core/error.hpp"
#include "rtslam/core/random.hpp"

namespace rtslam::filter::kernels {
namespace {

using Eigen::MatrixXd;

constexpr int kP = kPanelRows;

// Active rows of a 70 × 70 covariance: runs of 1 to 9 rows separated by holes, the last run ending at the last row.
struct Layout {
  std::vector<int> rows;
  std::vector<LaneGroup> groups;
  ActiveRows active() const { return {rows.data(), groups.data(), static_cast<int>(rows.size())}; }
};

Layout make_layout(const std::vector<std::pair<int, int>>& runs) {
  Layout l;
  for (const auto& [begin, length] : runs)
    for (int i = begin; i < begin + length; ++i) l.rows.push_back(i);
  const int n = static_cast<int>(l.rows.size());
  for (int g = 0; g < (n + kP - 1) / kP * 2; ++g) {
    LaneGroup lg;
    for (int lane = 0; lane < kGroupLanes && g * kGroupLanes + lane < n; ++lane) {
      const int i = g * kGroupLanes + lane;
      if (lg.segments == 0 || l.rows[static_cast<size_t>(i - 1)] != l.rows[static_cast<size_t>(i)] - 1) {
        lg.base[lg.segments++] = l.rows[static_cast<size_t>(i)] - lane;
      }
      lg.mask[lg.segments - 1] |= 1u << lane;
    }
    l.groups.push_back(lg);
  }
  return l;
}

const std::vector<std::pair<int, int>> kRuns = {{0, 9}, {10, 3}, {14, 1}, {16, 7}, {25, 2}, {28, 8},
                                                {37, 5}, {43, 4}, {50, 6}, {57, 3}, {61, 9}};
constexpr int kCap = 70;

MatrixXd random_matrix(int r, int c, Rng& rng) {
  MatrixXd A(r, c);
  for (int i = 0; i < r; ++i)
    for (int j = 0; j < c; ++j) A(i, j) = randn(rng);
  return A;
}

// Packs the rows of a dense n × m matrix with the given panel stride; the padding (rows past n, columns past m) is
// `pad`.
std::vector<double> pack(const MatrixXd& W, int stride, double pad = 0.0) {
  const int n = static_cast<int>(W.rows());
  std::vector<double> out(static_cast<size_t>(packed_size(n, stride)), pad);
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < W.cols(); ++k) out[static_cast<size_t>((i / kP * stride + k) * kP + i % kP)] = W(i, k);
  return out;
}

MatrixXd unpack(const std::vector<double>& packed, int n, int m, int stride) {
  MatrixXd W(n, m);
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < m; ++k) W(i, k) = packed[static_cast<size_t>((i / kP * stride + k) * kP + i % kP)];
  return W;
}

// Runs f under each available instruction set and returns the results in KernelIsa order (generic, avx2, avx2_fma,
// avx512).
template <class F>
auto under_each_isa(F f) {
  std::vector<decltype(f())> out;
  for (const KernelIsa isa : {KernelIsa::generic, KernelIsa::avx2, KernelIsa::avx2_fma, KernelIsa::avx512}) {
    if (static_cast<int>(isa) <= static_cast<int>(best_kernel_isa())) out.push_back((set_kernel_isa(isa), f()));
  }
  set_kernel_isa(best_kernel_isa());
  return out;
}

// Largest |a − b| relative to the largest |a|.
double relative_difference(const MatrixXd& a, const MatrixXd& b) {
  return (a - b).cwiseAbs().maxCoeff() / std::max(a.cwiseAbs().maxCoeff(), 1e-300);
}

bool bit_identical(const MatrixXd& a, const MatrixXd& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() &&
         std::equal(a.data(), a.data() + a.size(), b.data(),
                    [](double x, double y) { return std::memcmp(&x, &y, sizeof(double)) == 0; });
}

// Whether the downdate has tiles on both of its AVX2 paths below the diagonal: 8 consecutive covariance rows
// against 4 consecutive columns (plain loads and stores), and tiles across holes (masked).
bool has_both_tile_kinds(const Layout& l) {
  const auto full = [](const LaneGroup& g) { return g.segments == 1 && g.mask[0] == 0xF; };
  bool plain = false, masked = false;
  const int n = l.active().n;
  for (int j0 = 0; j0 < n; j0 += 4) {
    for (int p = j0 / kP + 1; p * kP < n; ++p) {
      const LaneGroup &gc = l.groups[static_cast<size_t>(j0 / 4)], &gl = l.groups[static_cast<size_t>(2 * p)],
                      &gh = l.groups[static_cast<size_t>(2 * p + 1)];
      (full(gc) && full(gl) && full(gh) && gh.base[0] == gl.base[0] + kGroupLanes ? plain : masked) = true;
    }
  }
  return plain && masked;
}

TEST(FilterKernels, DowndateMatchesDenseOnActiveRowsAndLeavesHolesUntouched) {
  Rng rng(5);
  // kRuns: 57 active rows (the last strip has 1 column); without the last run's last 3 rows, 54 (a last strip of 6
  // columns, both halves, and the diagonal tile with columns past n).
  std::vector<std::pair<int, int>> short_runs = kRuns;
  short_runs.back().second -= 3;
  for (int layout = 0; layout < 2; ++layout) {
    const Layout l = make_layout(layout == 0 ? kRuns : short_runs);
    if (layout == 0) {
      ASSERT_TRUE(has_both_tile_kinds(l));
    }
    const int n = l.active().n;
    MatrixXd P0 = random_matrix(kCap, kCap, rng);
    P0 = (P0 + P0.transpose()).eval();
    for (const int m : {1, 2, 7, 44}) {
      const MatrixXd W = random_matrix(n, m, rng);
      const int stride = m + 3;  // a pending factor's panels hold more columns than are used
      // Padding NaN: the kernels compute with the lanes past n (whole registers) but must write none of them.
      const std::vector<double> packed = pack(W, stride, std::numeric_limits<double>::quiet_NaN());
      const auto results = under_each_isa([&] {
        MatrixXd P = P0;
        downdate_mirrored(P.data(), P.outerStride(), l.active(), packed.data(), m, stride);
        return P;
      });
      MatrixXd expected = P0;
      for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) expected(l.rows[a], l.rows[b]) -= W.row(a).dot(W.row(b));
      for (const MatrixXd& P : results) {
        ASSERT_TRUE(P.allFinite()) << "m = " << m;  // (maxCoeff may skip a NaN)
        EXPECT_LT((P - expected).cwiseAbs().maxCoeff(), 1e-12) << "m = " << m;
        EXPECT_TRUE(bit_identical(P, P.transpose())) << "m = " << m;
        // Holes: rows and columns of no run are neither read into nor written.
        for (int i = 0; i < kCap; ++i) {
          const bool active_i = std::find(l.rows.begin(), l.rows.end(), i) != l.rows.end();
          for (int j = 0; j < kCap; ++j) {
            const bool active_j = std::find(l.rows.begin(), l.rows.end(), j) != l.rows.end();
            if (!(active_i && active_j)) {
              ASSERT_EQ(P(i, j), P0(i, j)) << i << "," << j;
            }
          }
        }
      }
      if (results.size() >= 2) {
        EXPECT_TRUE(bit_identical(results[0], results[1])) << "m = " << m;
      }
      if (results.size() >= 3) {  // fused multiply-adds: the same sums, rounded once per term
        EXPECT_LT(relative_difference(results[2], results[0]), 1e-14) << "m = " << m;
        if (m == 44) {
          EXPECT_FALSE(bit_identical(results[2], results[0])) << "the FMA variant is not fused";
        }
      }
      if (results.size() == 4) {  // AVX-512 tiles: the AVX2 + FMA variant's operations, element by element
        EXPECT_TRUE(bit_identical(results[3], results[2])) << "m = " << m;
      }
    }
  }
}

// The AVX-512 downdate on a map-sized layout (the landmarks' runs of 7 and 3 rows, long runs where blocks were
// allocated back to back, one-row holes; 326 active rows of 360): every kind of its tiles occurs many times (both
// panels of a pair plain, masked, mixed; the odd last panel; the diagonal ones), and each gives the avx2_fma bytes.
TEST(FilterKernels, Avx512DowndateGivesTheFmaVariantsBytesOnAMapSizedLayout) {
  if (best_kernel_isa() < KernelIsa::avx512) GTEST_SKIP() << "no AVX-512 on this CPU: " << to_string(best_kernel_isa());
  std::vector<std::pair<int, int>> runs;
  int next = 0;
  for (int r = 0; next < 340; ++r) {
    const int length = r % 5 == 4 ? 24 + r : (r % 2 == 0 ? 7 : 3);
    runs.emplace_back(next, length);
    next += length + 1;
  }
  runs.back().second -= next - 1 - 355;  // the last run ends at row 354
  const Layout l = make_layout(runs);
  const int n = l.active().n;
  int plain_pairs = 0, masked = 0;
  for (int p = 0; p < n / kP; ++p) {
    const LaneGroup &gl = l.groups[static_cast<size_t>(2 * p)], &gh = l.groups[static_cast<size_t>(2 * p + 1)];
    (gl.segments == 1 && gl.mask[0] == 0xF && gh.segments == 1 && gh.mask[0] == 0xF &&
             gh.base[0] == gl.base[0] + kGroupLanes
         ? plain_pairs
         : masked)++;
  }
  ASSERT_GE(plain_pairs, 8);
  ASSERT_GE(masked, 8);
  Rng rng(9);
  MatrixXd P0 = random_matrix(360, 360, rng);
  P0 = (P0 + P0.transpose()).eval();
  for (const int m : {3, 50}) {
    const MatrixXd W = random_matrix(n, m, rng);
    const std::vector<double> packed = pack(W, m + 1, std::numeric_limits<double>::quiet_NaN());
    MatrixXd by_fma = P0, by_avx512 = P0;
    set_kernel_isa(KernelIsa::avx2_fma);
    downdate_mirrored(by_fma.data(), by_fma.outerStride(), l.active(), packed.data(), m, m + 1);
    set_kernel_isa(KernelIsa::avx512);
    downdate_mirrored(by_avx512.data(), by_avx512.outerStride(), l.active(), packed.data(), m, m + 1);
    set_kernel_isa(best_kernel_isa());
    ASSERT_TRUE(by_avx512.allFinite());
    EXPECT_TRUE(bit_identical(by_avx512, by_fma)) << "m = " << m;
    EXPECT_FALSE(bit_identical(by_avx512, P0));
  }
}

TEST(FilterKernels, PHtSolveAndProductMatchDenseAndAgreeAcrossInstructionSets) {
  Rng rng(6);
  const Layout l = make_layout(kRuns);
  const int n = l.active().n;
  const MatrixXd P = random_matrix(kCap, kCap, rng);
  const int m = 11;
  const MatrixXd H = random_matrix(m, 9, rng);
  const std::vector<int> cols = {0, 2, 3, 7};  // H's columns 1, 4, 5, 6, 8 are treated as zero
  MatrixXd L = random_matrix(m, m, rng).triangularView<Eigen::Lower>();
  L.diagonal() = L.diagonal().cwiseAbs() + MatrixXd::Ones(m, 1) * 2.0;
  const int mu = 5;
  const MatrixXd U = random_matrix(n, mu, rng);
  const MatrixXd G = random_matrix(mu, m, rng);
  const std::vector<double> U_packed = pack(U, mu + 2);
  const auto results = under_each_isa([&] {
    std::vector<double> W(static_cast<size_t>(packed_size(n, m)), 0.0);
    // P(:, 30 + c) H(k, c)ᵀ on rows [2, 9) of H.
    add_P_Ht(ConstMatrixView{P.data(), P.outerStride()}, l.active(), 30, cols.data(), static_cast<int>(cols.size()),
             ConstMatrixView{H.data(), H.outerStride()}, 0, 2, 9, W.data(), m);
    const MatrixXd PHt = unpack(W, n, m, m);
    solve_lower_transposed(W.data(), n, m, ConstMatrixView{L.data(), L.outerStride()});
    const MatrixXd solved = unpack(W, n, m, m);
    subtract_product(W.data(), n, m, U_packed.data(), mu, mu + 2, ConstMatrixView{G.data(), G.outerStride()});
    const MatrixXd reduced = unpack(W, n, m, m);
    return std::vector<MatrixXd>{PHt, solved, reduced};
  });
  MatrixXd PHt = MatrixXd::Zero(n, m);
  for (int i = 0; i < n; ++i)
    for (int k = 2; k < 9; ++k)
      for (int c : cols) PHt(i, k) += P(l.rows[i], 30 + c) * H(k, c);
  const MatrixXd solved = L.triangularView<Eigen::Lower>().solve(PHt.transpose()).transpose();
  const MatrixXd reduced = solved - U * G;
  for (const auto& r : results) {
    EXPECT_LT((r[0] - PHt).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((r[1] - solved).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((r[2] - reduced).cwiseAbs().maxCoeff(), 1e-12);
  }
  if (results.size() >= 2) {
    for (size_t k = 0; k < 3; ++k) EXPECT_TRUE(bit_identical(results[0][k], results[1][k])) << k;
  }
  if (results.size() == 4) {  // the AVX-512 level uses the AVX2 + FMA versions of these
    for (size_t k = 0; k < 3; ++k) EXPECT_TRUE(bit_identical(results[3][k], results[2][k])) << k;
  }
  if (results.size() >= 3) {
    for (size_t k = 0; k < 3; ++k) {
      EXPECT_LT(relative_difference(results[2][k], results[0][k]), 1e-13) << k;
      EXPECT_FALSE(bit_identical(results[2][k], results[0][k])) << k << ": the FMA variant is not fused";
    }
  }
}

// A block's own share of W Wᵀ (the diagonal blocks of a correction): every level gives the generic sums bit for bit,
// close to a dense reference, for blocks that start anywhere in a panel and span one to four panels. W's padding
// (rows past n, columns past m) is NaN, so a sum that read it would show; G starts NaN, so an element the kernel
// failed to write would show, and it must stay NaN above the diagonal and past t.
TEST(FilterKernels, BlockGramGivesTheGenericSumsOnEveryLevel) {
  Rng rng(8);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const int n = 45, ldG = 24;
  for (const int m : {1, 7, 50}) {
    const MatrixXd W = random_matrix(n, m, rng);
    const std::vector<double> packed = pack(W, m + 3, nan);
    std::vector<std::pair<int, int>> blocks;  // (i0, t): starts anywhere in a panel, and blocks ending at row n - 1
    for (int i0 = 0; i0 < 18; ++i0)
      for (const int t : {1, 2, 3, 4, 5, 7, 8, 9, 15, 18, 20}) blocks.emplace_back(i0, t);
    for (int t = 1; t <= 20; ++t) blocks.emplace_back(n - t, t);  // the last, partly filled panel (NaN padding)
    for (const auto& block : blocks) {
      const int i0 = block.first, t = block.second;  // (a lambda below uses them: no structured binding)
      const auto results = under_each_isa([&] {
        MatrixXd G = MatrixXd::Constant(ldG, ldG, nan);
        block_gram(packed.data(), m, m + 3, i0, t, G.data(), ldG);
        return G;
      });
      const MatrixXd Wb = W.middleRows(i0, t);
      const MatrixXd ref = Wb * Wb.transpose();
      for (size_t level = 0; level < results.size(); ++level) {
        const MatrixXd& G = results[level];
        for (int c = 0; c < ldG; ++c) {
          for (int r = 0; r < ldG; ++r) {
            if (r < t && c <= r) {
              ASSERT_NEAR(G(r, c), ref(r, c), 1e-12 * (1.0 + std::abs(ref(r, c))))
                  << "m " << m << " i0 " << i0 << " t " << t << " (" << r << ", " << c << ") level " << level;
            } else {
              ASSERT_TRUE(std::isnan(G(r, c))) << "written outside the lower triangle: (" << r << ", " << c
                                               << "), m " << m << " i0 " << i0 << " t " << t << " level " << level;
            }
          }
        }
        for (int c = 0; c < t; ++c)
          for (int r = c; r < t; ++r)
            ASSERT_EQ(std::memcmp(&G(r, c), &results[0](r, c), sizeof(double)), 0) << "level " << level;
      }
    }
  }
}

TEST(FilterKernels, InstructionSetIsClampedToWhatTheCpuSupports) {
  EXPECT_EQ(set_kernel_isa(KernelIsa::avx512), best_kernel_isa());
  EXPECT_EQ(kernel_isa(), best_kernel_isa());
  const KernelIsa fma = set_kernel_isa(KernelIsa::avx2_fma);
  EXPECT_EQ(fma, std::min(best_kernel_isa(), KernelIsa::avx2_fma));
  EXPECT_EQ(kernel_isa(), fma);
  const KernelIsa plain = set_kernel_isa(KernelIsa::avx2);
  EXPECT_EQ(plain, best_kernel_isa() == KernelIsa::generic ? KernelIsa::generic : KernelIsa::avx2);
  EXPECT_EQ(kernel_isa(), plain);
  EXPECT_EQ(set_kernel_isa(KernelIsa::generic), KernelIsa::generic);
  EXPECT_STREQ(to_string(KernelIsa::avx2_fma), "avx2_fma");
  EXPECT_STREQ(to_string(KernelIsa::avx512), "avx512");
  set_kernel_isa(best_kernel_isa());
}

TEST(FilterKernels, TheEnvironmentVariableSelectsALevelClampedToTheCpuAndNamesABadValue) {
  for (const KernelIsa isa : {KernelIsa::generic, KernelIsa::avx2, KernelIsa::avx2_fma, KernelIsa::avx512}) {
    EXPECT_EQ(parse_kernel_isa(to_string(isa)), isa);
    EXPECT_EQ(kernel_isa_from_env(to_string(isa)), std::min(isa, best_kernel_isa())) << to_string(isa);
  }
  EXPECT_EQ(kernel_isa_from_env(nullptr), best_kernel_isa());
  EXPECT_EQ(kernel_isa_from_env(""), best_kernel_isa());
  EXPECT_FALSE(parse_kernel_isa("AVX2"));
  try {
    kernel_isa_from_env("sse9");
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("RTSLAM_KERNEL_ISA: 'sse9' is not"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rtslam::filter::kernels
