#!/usr/bin/env bash
# One command from a fresh clone: install, build, and run every test (GoogleTest via CTest, plus
# the CLI end-to-end test). Real scenes are read from ../shared/data/scenes.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
ctest --test-dir "${BUILD_DIR:-build}" --output-on-failure -j"$(nproc)"
