// The sanitizer build's check of itself (registered only with RTSLAM_SANITIZE, docs/testing.md "Build time"):
// UndefinedBehaviorSanitizer still checks our code now that cmake/ubsan-ignore.txt leaves Eigen's headers out of it,
// and AddressSanitizer still checks the memory accesses made inside Eigen.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <limits>
#include <memory>

namespace {

int next_int(int x) { return x + 1; }

TEST(Sanitizers, UndefinedBehaviourInOurCodeIsReported) {
  volatile int big = std::numeric_limits<int>::max();
  EXPECT_DEATH(
      {
        volatile int r = next_int(big);
        (void)r;
      },
      "signed integer overflow");
}

TEST(Sanitizers, OutOfBoundsReadsInsideEigenAreReported) {
  auto buf = std::make_unique<double[]>(3);
  for (int i = 0; i < 3; ++i) buf[i] = i;
  volatile int n = 4;  // one past the allocation
  EXPECT_DEATH(
      {
        const Eigen::Map<const Eigen::VectorXd> v(buf.get(), n);
        volatile double s = v.sum();
        (void)s;
      },
      "heap-buffer-overflow");
}

}  // namespace
