#!/usr/bin/env bash
# Installs what gshaptics needs from Debian's packages (only what is missing), then configures
# and builds it in ./build (Release). Used by demo.sh and test.sh; safe to run repeatedly.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(cmake g++ make pkg-config libeigen3-dev libcli11-dev nlohmann-json3-dev libfmt-dev libfcl-dev libnanoflann-dev
          zlib1g-dev libzstd-dev libxxhash-dev libmujoco-dev libqhull-dev
          libgtest-dev libgmock-dev libbenchmark-dev python3 python3-dev python3-numpy python3-matplotlib
          python3-pytest pybind11-dev clang libclang-rt-14-dev
          libboost-dev chromium
          cyclonedds-dev cyclonedds-tools
          libfastrtps-dev fastddsgen default-jre-headless
          libroscpp-dev ros-core libgeometry-msgs-dev libvisualization-msgs-dev
          python3-rostopic python3-geometry-msgs python3-visualization-msgs)
# The viewer's front-end packages come from npm (web/package-lock.json); Node.js from Debian
# only when the machine has none.
command -v node > /dev/null 2>&1 || PACKAGES+=(nodejs npm)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# three.js, Spark and playwright-core, pinned by web/package-lock.json; nothing from a CDN at
# run time. Reinstalled only when the lock file changed.
if [ ! -f web/node_modules/.package-lock.json ] || [ web/package-lock.json -nt web/node_modules/.package-lock.json ]; then
  echo "setup: npm ci in web/"
  npm ci --prefix web --no-audit --no-fund --loglevel=error
fi

BUILD_DIR=${BUILD_DIR:-build}
cmake -S . -B "$BUILD_DIR" -DCMAKE_BUILD_TYPE=Release -DGSHAPTICS_BUILD_TESTS=ON -DGSHAPTICS_BUILD_BENCHMARKS=ON -DGSHAPTICS_BUILD_PYTHON=ON ${CMAKE_ARGS:-}
cmake --build "$BUILD_DIR" -j"$(nproc)"
