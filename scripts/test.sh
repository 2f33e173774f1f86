#!/usr/bin/env bash
# The test command: installs dependencies, builds with warnings as errors, runs the suite (all but the `slow`
# label), then builds and runs it again under AddressSanitizer + UndefinedBehaviorSanitizer. The fuzz findings run
# in both as tests/io/test_fuzz_regressions; the clang fuzz targets and their campaigns (`bash scripts/fuzz.sh`)
# stay out of this command for the CI time budget (docs/testing.md, "Build time": a clang sanitizer build that also
# fuzzes was measured at 23 min for this command, against 20 with GCC's).
# Long acceptance runs: `ctest --test-dir build -L slow` (see docs/testing.md).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/deps.sh
jobs=$(nproc)

# Debian's interpreter for the Python module and its test (deps.sh installs its numpy; a python3 found first on the
# PATH, e.g. pyenv's, may lack it and test_python would then not be registered).
python_opt=()
[[ -x /usr/bin/python3 ]] && python_opt=(-DPython3_EXECUTABLE=/usr/bin/python3)
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DRTSLAM_WERROR=ON "${python_opt[@]}"
cmake --build build -j "$jobs"
ctest --test-dir build -LE slow --output-on-failure -j "$jobs"

# -Og with line tables only: about half the compile time of -O2 -g (Eigen-heavy test files) and 30 % less than -O1
# (the tests then run 15-30 % slower: a net gain of about 1.5 min on 2 cores), and sanitizer reports still name
# files and lines. Without the ROS parts: their tests exercise ROS's own (uninstrumented) libraries more
# than ours, the Release suite runs them, and they cost ~2 min of the CI budget.
cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-Og -g1 -DNDEBUG" \
  -DRTSLAM_WERROR=ON -DRTSLAM_SANITIZE=ON -DRTSLAM_BUILD_BENCH=OFF -DRTSLAM_WITH_ROS=OFF
cmake --build build-asan -j "$jobs"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-asan -LE "slow|no-asan" --output-on-failure -j "$jobs"
