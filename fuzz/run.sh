#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan) and fuzzes every scene reader, every parser
# of a peer's WebSocket message and the parsers of the text files a user gives (registration
# JSON, pose log) for SECONDS each (default 60), starting from seeds cut out of the real scenes
# and from the documented forms. Exits non-zero on any finding (crash,
# sanitizer report, leak, timeout, out-of-memory, an escaped exception). Artifacts: build-fuzz/.
# Compiles and runs go FUZZ_JOBS at a time (default: one per core).
# Usage: fuzz/run.sh [SECONDS] [TARGET...]
#   (targets: ply compressed_ply splat spz viewer_message haply_message registration pose_log)
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_EACH=${1:-60}
shift || true
FORMATS=("${@:-ply compressed_ply splat spz viewer_message haply_message registration pose_log}")
FORMATS=(${FORMATS[@]})
SCENES=${GSHAPTICS_SCENES_DIR:-$(pwd)/../shared/data/scenes}
OUT=build-fuzz

need=()
for p in clang libclang-rt-14-dev libeigen3-dev nlohmann-json3-dev zlib1g-dev libzstd-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || need+=("$p")
done
if [ ${#need[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}"
fi

mkdir -p "$OUT/obj"
CXX="clang++ -std=c++20 -O1 -g -fno-omit-frame-pointer -Iinclude -I/usr/include/eigen3"
SAN="-fsanitize=address,undefined -fno-sanitize-recover=undefined"
# Compiles and fuzz runs go JOBS at a time (one per core): the compiles were most of the time.
JOBS=${FUZZ_JOBS:-$(nproc)}
pids=()
limit() {  # waits until fewer than JOBS of `pids` run
  while :; do
    local running=0
    for p in "${pids[@]}"; do kill -0 "$p" 2>/dev/null && running=$((running + 1)); done
    [ "$running" -lt "$JOBS" ] && return
    sleep 0.2
  done
}
wait_all() {  # waits for every job of `pids`; non-zero when any failed
  local rc=0
  for p in "${pids[@]}"; do wait "$p" || rc=1; done
  pids=()
  return $rc
}
# The loaders and what they use, compiled once with coverage and sanitizers.
SOURCES=(src/error.cpp src/io/atomic_file.cpp src/io/mapped_file.cpp src/io/ply_reader.cpp src/io/splat_reader.cpp
         src/io/compressed_ply_reader.cpp src/io/spz_reader.cpp src/io/scene_loader.cpp
         src/io/scene_writer.cpp src/io/gaussian_scene.cpp)
objs=()
for s in "${SOURCES[@]}"; do
  o="$OUT/obj/$(basename "${s%.cpp}").o"
  limit
  $CXX $SAN -fsanitize=fuzzer-no-link -c "$s" -o "$o" &
  pids+=($!)
  objs+=("$o")
done
# The messages' seeds: the documented forms (haply: a first byte picks the device index).
mkdir -p "$OUT/seeds/viewer_message" "$OUT/seeds/haply_message"
printf '%s' '{"type":"tool","center":[0.1,-0.2,0.3]}' > "$OUT/seeds/viewer_message/plain.json"
printf '%s' '{"type":"tool","center":[0,0,0.5],"rotation":[0.7071,0,0,0.7071]}' > "$OUT/seeds/viewer_message/rotated.json"
printf '%s' '0{"inverse3":[{"device_id":"INV3-0","config":{"handedness":"right"},"state":{"cursor_position":{"x":0.01,"y":-0.02,"z":0.15},"cursor_velocity":{"x":0.1,"y":0,"z":-0.3}}}],"wireless_verse_grip":[{"device_id":"VG","state":{"orientation":{"w":1,"x":0,"y":0,"z":0},"buttons":{"a":true,"b":false,"c":true}}}]}' \
  > "$OUT/seeds/haply_message/state.json"
printf '%s' '1{"inverse3":[{"state":{"cursor_position":{"x":0,"y":0,"z":0}}}]}' > "$OUT/seeds/haply_message/short_list.json"
# The text files' seeds: the bundled registration, a pose log with every column.
mkdir -p "$OUT/seeds/registration" "$OUT/seeds/pose_log"
cp data/truck.registration.json "$OUT/seeds/registration/"
printf '%s\n' '{"matrix": [[1,0,0],[0,0,-1],[0,1,0]], "translation": [0, 0, 0.5]}' > "$OUT/seeds/registration/matrix.json"
printf 'time_s,x,y,z,vx,vy,vz,qw,qx,qy,qz\n0,0,0,0.1,0,0,0,1,0,0,0\n0.001,0.01,0,0.1,1,0,0,1,0,0,0\n' \
  > "$OUT/seeds/pose_log/full.csv"
printf 'time_s,x,y,z\n0,0,0,0\n0.5,1e-3,nan,0\n' > "$OUT/seeds/pose_log/minimal.csv"

for f in "${FORMATS[@]}"; do
  def=$(echo "$f" | tr a-z A-Z)
  limit
  case "$f" in
    *_message) $CXX $SAN -fsanitize=fuzzer -DGSHAPTICS_FUZZ_${def} fuzz/fuzz_messages.cpp src/device/peer_messages.cpp \
                 -o "$OUT/fuzz_$f" & ;;
    registration) $CXX $SAN -fsanitize=fuzzer -DGSHAPTICS_FUZZ_${def} fuzz/fuzz_text.cpp src/scene/registration.cpp \
                    src/scene/sh_rotation.cpp src/io/gaussian_scene.cpp src/io/mapped_file.cpp src/error.cpp -o "$OUT/fuzz_$f" & ;;
    pose_log) $CXX $SAN -fsanitize=fuzzer -DGSHAPTICS_FUZZ_${def} fuzz/fuzz_text.cpp src/device/replay_device.cpp \
                src/io/mapped_file.cpp src/error.cpp -o "$OUT/fuzz_$f" & ;;
    *) continue ;;  # (the loaders' targets link the objects above: built below)
  esac
  pids+=($!)
done
wait_all || { echo "fuzz: compiling failed"; exit 1; }
# Seeds: a helper linked with the loaders' objects writes small valid files of every format.
limit
$CXX $SAN -fsanitize=fuzzer-no-link "fuzz/make_seeds.cpp" "${objs[@]}" -lz -lzstd -o "$OUT/make_seeds" &
pids+=($!)
for f in "${FORMATS[@]}"; do
  case "$f" in
    *_message | registration | pose_log) ;;
    *) def=$(echo "$f" | tr a-z A-Z)
       limit
       $CXX $SAN -fsanitize=fuzzer -DGSHAPTICS_FUZZ_${def} fuzz/fuzz_loader.cpp "${objs[@]}" -lz -lzstd -o "$OUT/fuzz_$f" &
       pids+=($!) ;;
  esac
done
wait_all || { echo "fuzz: compiling a target failed"; exit 1; }
"$OUT/make_seeds" "$SCENES" "$OUT/seeds"
for f in "${FORMATS[@]}"; do
  mkdir -p "$OUT/corpus/$f" "$OUT/artifacts/$f"
  rm -f "$OUT/fuzz_$f.failed"
  echo "fuzz: $f for ${SECONDS_EACH}s"
  limit
  ( "$OUT/fuzz_$f" "$OUT/corpus/$f" "$OUT/seeds/$f" -max_total_time="$SECONDS_EACH" -max_len=65536 \
      -rss_limit_mb=2048 -timeout=10 -print_final_stats=1 -artifact_prefix="$OUT/artifacts/$f/" \
      > "$OUT/fuzz_$f.log" 2>&1 || touch "$OUT/fuzz_$f.failed" ) &
  pids+=($!)
done
wait_all || true
status=0
for f in "${FORMATS[@]}"; do
  if [ -e "$OUT/fuzz_$f.failed" ]; then
    echo "fuzz: $f FAILED (see $OUT/fuzz_$f.log and $OUT/artifacts/$f/)"; tail -30 "$OUT/fuzz_$f.log"; status=1
  else
    echo "fuzz: $f ok: $(grep -E 'stat::number_of_executed_units' "$OUT/fuzz_$f.log" | awk '{print $2}') runs, $(grep -E 'stat::new_units_added' "$OUT/fuzz_$f.log" | awk '{print $2}') new units, $(grep -oE 'cov: [0-9]+' "$OUT/fuzz_$f.log" | tail -1)"
  fi
done
exit $status
