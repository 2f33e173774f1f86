#!/usr/bin/env bash
# Installs the Debian packages rtslam needs to build, test and report (idempotent; run as root).
set -euo pipefail
packages=(
  cmake g++ ninja-build pkg-config ccache
  # the test command's sanitizer build and its fuzz targets (scripts/test.sh), and the linker of both builds
  clang lld libfuzzer-14-dev libclang-rt-14-dev
  libeigen3-dev libopencv-dev libdeflate-dev libyaml-cpp-dev libcli11-dev libfmt-dev libspdlog-dev
  # FFmpeg's libraries (OpenCV's video I/O; the variable-frame-rate video test writes its file with them)
  libavformat-dev libavcodec-dev libavutil-dev
  libgtest-dev libgmock-dev libbenchmark-dev nlohmann-json3-dev gnuplot-nox chromium
  libcivetweb-dev nodejs
  # ROS1 (optional at build time, RTSLAM_WITH_ROS; docs/ros.md): bags, the rtslam_ros node, rosmaster for its test
  librosbag-storage-dev libroscpp-dev libsensor-msgs-dev libnav-msgs-dev libtf2-msgs-dev python3-rosmaster
  # Python bindings (optional at build time, RTSLAM_PYTHON; docs/python.md): pybind11, the headers, numpy for the tests
  pybind11-dev python3-dev python3-numpy
)
# npm fetches the viewer's three.js at build time; Debian's nodejs lacks it, NodeSource's ships it.
command -v npm >/dev/null 2>&1 || packages+=(npm)
packages+=("$@")  # extra packages a script needs (scripts/fuzz.sh: clang and libFuzzer)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "deps: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
# npm (the viewer's three.js and the browser tests' playwright-core, web/package-lock.json): Node.js builds that
# bundle it (e.g. NodeSource's) need nothing more; Debian's nodejs needs Debian's npm.
if ! command -v npm >/dev/null 2>&1; then
  echo "deps: installing npm"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends npm >/dev/null
fi
