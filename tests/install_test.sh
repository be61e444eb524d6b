#!/usr/bin/env bash
# CTest: install the built library into a fresh prefix, build examples/ against it with
# find_package(gshaptics) as an outside project would, and run the example on the bundled Truck.
# Usage: install_test.sh BUILD_DIR SOURCE_DIR WORK_DIR
set -euo pipefail
build=$1 src=$2 work=$3
rm -rf "$work"
mkdir -p "$work"
# Everything but the Python module (its install goes to the interpreter's site-packages).
cmake --install "$build" --prefix "$work/prefix" --component Unspecified > "$work/install.log"
for h in error.h io/scene_loader.h collision/contact_query.h servo/haptic_runtime.h sim/probe_run.h net/contact_snapshot.h; do
  [ -f "$work/prefix/include/gshaptics/$h" ] || { echo "FAIL: header $h not installed"; exit 1; }
done
for d in ros1 ros2; do
  [ ! -e "$work/prefix/include/gshaptics/$d" ] || { echo "FAIL: $d headers installed without their library"; exit 1; }
done
# Every script a command runs (find_tool_script in the sources) is in the prefix's share folder.
for script in $(grep -rhoE 'find_tool_script\("[A-Za-z0-9_.-]+"\)' "$src/src" "$src/apps" | sed -E 's/.*\("(.*)"\)/\1/' | sort -u); do
  [ -f "$work/prefix/share/gshaptics/$script" ] || { echo "FAIL: $script, which a command runs, is not installed"; exit 1; }
done
cmake -S "$src/examples" -B "$work/build" -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release > "$work/configure.log"
cmake --build "$work/build" -j2 > "$work/build.log"
"$work/build/gshaptics_embed" "$src/data"
# The installed CLI serves the viewer page from the prefix, with every file the page loads.
if [ -x "$work/prefix/bin/gshaptics" ] && [ -d "$src/web/node_modules/three" ]; then
  /usr/bin/python3 "$src/tests/install_serve_check.py" "$work/prefix" "$src/data"
fi
echo "1 passed, 0 failed"
