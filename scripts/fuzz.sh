#!/usr/bin/env bash
# Fuzzing (docs/testing.md, "Fuzzing"): builds the libFuzzer targets of fuzz/ with clang in build-fuzz/, replays
# the committed corpora once (fuzz/corpus/<target>/: seeds and the inputs of past findings), then fuzzes each
# target for SECONDS (default 600), FUZZ_JOBS targets at a time (default 1: the machine has 2 shared cores).
#
#   bash scripts/fuzz.sh [SECONDS] [TARGET...]      e.g.  bash scripts/fuzz.sh 60 calib_rig trajectory
#   bash scripts/fuzz.sh 0                          build and replay only, no fuzzing
#   FUZZ_BUILD=build-asan FUZZ_JOBS=2 bash scripts/fuzz.sh 20
#                                                   the targets the test command's sanitizer build already made
#                                                   (scripts/test.sh runs this): no configure, no build, no replay
#                                                   (its ctest run replayed the corpora)
#
# Seeds: fuzz/corpus/<target>/ (committed, small) and <build>/seeds/<target>/, made here from
# ../shared/datasets when it exists (never committed). The corpus a run grows is kept in <build>/corpus/<target>/
# and used by the next run. Findings (crash-*, timeout-*, oom-*, leak-*) go to <build>/findings/<target>/, logs
# to <build>/logs/<target>.log, one line per target to <build>/logs/summary.txt (<build>: build-fuzz or FUZZ_BUILD).
# Exits non-zero if the replay fails or any target has a finding.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
seconds=${1:-600}
if (($# > 0)); then shift; fi
all_targets=(yaml_config calib_euroc calib_kalibr calib_monoslam calib_kitti calib_rig trajectory dataset_lists
  image_decode imu_stream)
targets=("$@")
((${#targets[@]})) || targets=("${all_targets[@]}")
# Inputs longer than the files each parser meets are wasted time.
declare -A max_len=([yaml_config]=4096 [calib_euroc]=4096 [calib_kalibr]=8192 [calib_monoslam]=2048
  [calib_kitti]=4096 [calib_rig]=4096 [trajectory]=8192 [dataset_lists]=8192 [image_decode]=16384
  [imu_stream]=4096)
for t in "${targets[@]}"; do
  [[ -n "${max_len[$t]:-}" ]] || { echo "fuzz: unknown target '$t' (known: ${all_targets[*]})" >&2; exit 2; }
done

jobs=${FUZZ_JOBS:-1}
[[ "$jobs" =~ ^[1-9][0-9]*$ ]] || { echo "fuzz: FUZZ_JOBS must be a positive integer, not '$jobs'" >&2; exit 2; }
export ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
if [[ -n "${FUZZ_BUILD:-}" ]]; then
  out=$(cd "$FUZZ_BUILD" && pwd)
  for t in "${targets[@]}"; do
    [[ -x "$out/fuzz/fuzz_$t" ]] || { echo "fuzz: $out/fuzz/fuzz_$t not built (configure with -DRTSLAM_FUZZ=ON)" >&2; exit 2; }
  done
  # The targets write their inputs to a scratch folder under TMPDIR: keep it (and what a crash leaves) in the build.
  export TMPDIR=$out/fuzz-tmp
  rm -rf "$TMPDIR" && mkdir -p "$TMPDIR" "$out/logs"
else
  bash scripts/deps.sh clang libfuzzer-14-dev libclang-rt-14-dev
  # ccache when installed comes from CMakeLists.txt (RTSLAM_CCACHE), with the settings the precompiled headers need.
  cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1" \
    -DCMAKE_CXX_COMPILER=clang++ -DRTSLAM_FUZZ=ON -DRTSLAM_ONLY_MODULES="core;io" \
    -DRTSLAM_BUILD_TESTS=OFF -DRTSLAM_BUILD_BENCH=OFF >/dev/null
  cmake --build build-fuzz -j "$(nproc)"
  out=$root/build-fuzz
  export TMPDIR=$out/tmp
  rm -rf "$TMPDIR" && mkdir -p "$TMPDIR" "$out/logs"
  echo "fuzz: replaying fuzz/corpus/"
  ctest --test-dir build-fuzz/fuzz --output-on-failure
fi
if ((seconds == 0)); then
  echo "fuzz: replay only (SECONDS is 0), no fuzzing"
  exit 0
fi

# Seeds from the shared datasets: short heads of their text files, small crops of their images.
data=$root/../shared/datasets
seeds=$out/seeds
rm -rf "$seeds"
for t in "${all_targets[@]}"; do mkdir -p "$seeds/$t"; done
if [[ -d "$data" ]]; then
  head_to() { [[ -f "$1" ]] && head -n "$3" "$1" >"$seeds/$2/$(basename "$(dirname "$1")")-$(basename "$1")" || true; }
  euroc=$data/euroc-v101-static/mav0
  for f in "$euroc"/*/sensor.yaml "$euroc"/body.yaml; do
    head_to "$f" calib_euroc 200
    head_to "$f" yaml_config 200
  done
  head_to "$euroc/imu0/sensor.yaml" calib_kalibr 200
  cp config/*.yaml config/sim/*.yaml "$seeds/yaml_config/"
  head_to "$data/monoslam-davison/camera.json" calib_monoslam 200
  head_to "$data/monoslam-davison/init/initial_state.json" calib_monoslam 200
  for f in "$data"/euroc-groundtruth/*.txt "$data"/euroc-v101-static/groundtruth/* \
    "$euroc/state_groundtruth_estimate0/data.csv"; do
    head_to "$f" trajectory 40
  done
  # fuzz_dataset_lists reads its first byte as the dataset: 'e' for EuRoC lists.
  for f in "$euroc"/cam0/data.csv "$euroc"/cam1/data.csv "$euroc"/imu0/data.csv; do
    { printf e; head -n 30 "$f"; } >"$seeds/dataset_lists/e-$(basename "$(dirname "$f")")-$(basename "$f")"
  done
  images=()
  for f in $(ls "$euroc"/cam0/data/*.png 2>/dev/null | head -n 2) \
    $(ls "$data"/monoslam-davison/frames/*.pgm 2>/dev/null | head -n 2); do
    images+=("$f")
  done
  ((${#images[@]})) && "$out/fuzz/fuzz_make_image_seeds" "$seeds/image_decode" "${images[@]}"
else
  echo "fuzz: $data not found: fuzzing from the committed seeds only"
fi

summary=$out/logs/summary.txt
: >"$summary"
# One target: fuzz for $seconds, then one summary line (and the finding's lines) in its own files.
fuzz_one() {
  local t=$1 rc=0
  rm -rf "$out/findings/$t"
  mkdir -p "$out/corpus/$t" "$out/findings/$t" "$out/logs/$t"
  # -jobs=1 -workers=1: one fuzzing process, its output copied into the log when it ends. Inputs that run longer
  # than 5 s, allocate more than 512 MB at once or grow the RSS above 2 GB are findings.
  (cd "$out/logs/$t" && "$out/fuzz/fuzz_$t" -jobs=1 -workers=1 -max_total_time="$seconds" \
    -max_len="${max_len[$t]}" -timeout=5 -rss_limit_mb=2048 -malloc_limit_mb=512 -print_final_stats=1 \
    -artifact_prefix="$out/findings/$t/" "$out/corpus/$t" "$root/fuzz/corpus/$t" "$seeds/$t") \
    >"$out/logs/$t.log" 2>&1 || rc=$?
  local log=$out/logs/$t.log
  final_stat() { sed -n "s/^stat::$1: *//p" "$log" | tail -n 1; }
  local last
  last=$(grep -E '^#[0-9]+' "$log" | tail -n 1 || true)
  status_field() { sed -n "s/.* $1: \([^ ]*\).*/\1/p" <<<"$last"; }
  local pcs found line
  pcs=$(sed -n 's/.*(\([0-9]*\) inline 8-bit counters).*/\1/p' "$log" | head -n 1)
  found=$(find "$out/findings/$t" -type f | wc -l)
  line="$t: ${seconds} s, $(final_stat number_of_executed_units) runs ($(final_stat average_exec_per_sec)/s), coverage $(status_field cov)"
  line+=" of ${pcs:-?} counters, $(status_field ft) features, corpus $(status_field corp); findings: $found (exit $rc)"
  echo "$line" >"$out/logs/$t.summary"
  rm -f "$out/logs/$t.failed"
  if ((rc != 0 || found > 0)); then
    grep -E 'fuzz finding|ERROR: |SUMMARY: |runtime error|Test unit written' "$log" | head -n 20 >"$out/logs/$t.failed" || true
    [[ -s "$out/logs/$t.failed" ]] || echo "exit $rc" >"$out/logs/$t.failed"
  fi
}
echo "fuzz: ${targets[*]} for $seconds s each, $jobs at a time"
running=0
for t in "${targets[@]}"; do
  if ((running >= jobs)); then
    wait -n || true
    running=$((running - 1))
  fi
  fuzz_one "$t" &
  running=$((running + 1))
done
wait || true
failed=()
for t in "${targets[@]}"; do
  line=$(cat "$out/logs/$t.summary" 2>/dev/null || echo "$t: no result (the fuzzing process did not report)")
  echo "fuzz: $line"
  echo "$line" >>"$summary"
  if [[ -f "$out/logs/$t.failed" || ! -f "$out/logs/$t.summary" ]]; then
    failed+=("$t")
    cat "$out/logs/$t.failed" 2>/dev/null || true
  fi
done
if ((${#failed[@]})); then
  echo "fuzz: FINDINGS in ${failed[*]} (inputs in $out/findings/, logs in $out/logs/)" >&2
  exit 1
fi
echo "fuzz: no findings (${targets[*]})"
