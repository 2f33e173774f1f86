#!/usr/bin/env bash
# The test command: installs dependencies, builds with warnings as errors, runs the suite (all but the `slow`
# label), then builds with clang under AddressSanitizer + UndefinedBehaviorSanitizer, runs the suite again there
# (with the fuzz findings' replays), and fuzzes each parser for a few seconds (scripts/fuzz.sh; the 10-minute
# campaigns are `bash scripts/fuzz.sh`, docs/testing.md).
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

# The sanitizer build with clang: it compiles our code under ASan + UBSan a little faster than GCC at -Og (462 vs 481 s
# on 2 cores, clean, 26 Nov), and builds the libFuzzer targets of fuzz/ in the same tree (only core and io get the
# fuzzer's coverage hooks), so that CI fuzzes every parser briefly. -O1 with
# line tables only: sanitizer reports still name files and lines. Without the ROS parts: their tests exercise ROS's
# own (uninstrumented) libraries more than ours, the Release suite runs them, and they cost ~2 min of the CI budget.
# UBSan leaves Eigen's headers out (cmake/ubsan-ignore.txt): the build ~15 % and the suite ~half shorter, our own
# code still fully checked (test_core_sanitizers). The tests' own code at -O0, but for the folders that compute
# heavily in it (tests/CMakeLists.txt rtslam_tests_optimized): ~95 s less on 2 cores (docs/testing.md).
# A build-asan/ configured with another compiler (GCC, before 26 Nov 2026) is started afresh.
if [[ -f build-asan/CMakeCache.txt ]] && ! grep -q '^CMAKE_CXX_COMPILER:[A-Z]*=.*clang++' build-asan/CMakeCache.txt; then
  rm -rf build-asan
fi
cmake -S . -B build-asan -G Ninja -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" -DRTSLAM_WERROR=ON -DRTSLAM_SANITIZE=ON -DRTSLAM_FUZZ=ON \
  -DRTSLAM_BUILD_BENCH=OFF -DRTSLAM_WITH_ROS=OFF
cmake --build build-asan -j "$jobs"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-asan -LE "slow|no-asan" --output-on-failure -j "$jobs"
# Every parser fuzzed briefly, 10 s each (about 50 s on 2 cores; new findings fail the command, their inputs land in
# build-asan/findings/). RTSLAM_CI_FUZZ_SECONDS changes the time; the 10-minute campaigns: docs/testing.md.
FUZZ_BUILD=build-asan FUZZ_JOBS="$jobs" bash scripts/fuzz.sh "${RTSLAM_CI_FUZZ_SECONDS:-10}"
