#!/usr/bin/env bash
# One command from a fresh clone: install, build, and run every test (GoogleTest, the CLI
# end-to-end test and pytest via CTest), then a one-minute libFuzzer run per input parser: scene
# readers, peer messages, registration, pose log (FUZZ_SECONDS=0 skips it). Real scenes are read from ../shared/data/scenes.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
ctest --test-dir "${BUILD_DIR:-build}" --output-on-failure -j"$(nproc)"
# Every input parser under libFuzzer (ASan + UBSan) for FUZZ_SECONDS each (0 skips).
fuzz_seconds=${FUZZ_SECONDS:-60}
if [ "$fuzz_seconds" -gt 0 ]; then
  fuzz/run.sh "$fuzz_seconds"
fi
