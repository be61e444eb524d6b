#!/usr/bin/env bash
# One command from a fresh clone: install, build, and run the simulated probe run on the bundled
# Truck scene. Leaves runs/truck/{probe_log.csv,summary.json,probe_run.png}.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
./build/apps/gshaptics simulate "$@"
