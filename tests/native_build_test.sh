#!/usr/bin/env bash
# CTest: GSHAPTICS_NATIVE=ON as an embedding project uses it. A project of its own adds gshaptics
# with the option on, then the embedding example (compiled with the project's own flags, not
# asked for -march=native), and runs it on the bundled Truck. The option must reach the example
# as a usage requirement: Eigen's fixed-size members change alignment under AVX, and code built
# without it that shares them with the library faults on the library's aligned loads.
# Usage: native_build_test.sh SOURCE_DIR WORK_DIR
set -euo pipefail
src=$1 work=$2
rm -rf "$work"
mkdir -p "$work/project"
cat > "$work/project/CMakeLists.txt" <<CMAKE
cmake_minimum_required(VERSION 3.21)
project(native_consumer LANGUAGES CXX)
set(GSHAPTICS_NATIVE ON CACHE BOOL "" FORCE)
foreach(o GSHAPTICS_BUILD_TESTS GSHAPTICS_BUILD_APPS GSHAPTICS_BUILD_VIEWER GSHAPTICS_BUILD_BENCHMARKS
          GSHAPTICS_BUILD_PYTHON GSHAPTICS_WITH_ROS1 GSHAPTICS_WITH_ROS2)
  set(\${o} OFF CACHE BOOL "" FORCE)
endforeach()
add_subdirectory("$src" gshaptics)
add_subdirectory("$src/examples" examples)
CMAKE
cmake -S "$work/project" -B "$work/build" -DCMAKE_BUILD_TYPE=Release > "$work/configure.log" 2>&1 ||
  { tail -30 "$work/configure.log"; exit 1; }
cmake --build "$work/build" --target gshaptics_embed -j2 > "$work/build.log" 2>&1 ||
  { tail -50 "$work/build.log"; exit 1; }
flags="$work/build/examples/CMakeFiles/gshaptics_embed.dir/flags.make"
grep -q -- "-march=native" "$flags" ||
  { echo "FAIL: the example was not compiled with -march=native ($flags)"; exit 1; }
"$work/build/examples/gshaptics_embed" "$src/data"
echo "1 passed, 0 failed"
