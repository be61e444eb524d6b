#!/usr/bin/env bash
# One command from a fresh clone: install, build, run the simulated probe run on the bundled
# Truck scene (as fast as the CPU allows), then 20 s of the same probe in real time through the
# runtime (servo thread at 1 kHz + collision worker). Leaves
# runs/truck-splat/{probe_log.csv,summary.json,probe_run.png} and runs/truck-splat/{servo_log.csv,
# run_summary.json,run.png}. Arguments go to `gshaptics simulate`.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
./build/apps/gshaptics simulate "$@"
echo
./build/apps/gshaptics run --duration 20
