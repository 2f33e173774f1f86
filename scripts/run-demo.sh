#!/usr/bin/env bash
# The main job: installs dependencies, builds rtslam, and runs it (no dataset: the built-in simulated demo).
# Extra arguments go to `rtslam run`, e.g. `bash scripts/run-demo.sh --seed 3 --out /tmp/out`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build -j "$(nproc)" --target rtslam
./build/apps/rtslam/rtslam run "$@"
