#!/usr/bin/env bash
# Proves find_package(vkjr2) works from an install prefix:
#   run.sh BUILD_DIR SOURCE_DIR [consumer|examples]
# installs BUILD_DIR into a temporary prefix, configures and builds a project
# against it (CMAKE_PREFIX_PATH only, with the same compiler, generator,
# build type and sanitizers as BUILD_DIR), runs it and removes everything it
# made. consumer (default): tests/package/consumer. examples: examples/minimal
# on face-api's demo photo and examples/host_pipeline on a short clip made
# from it with the installed `vkjr2 simulate` (tilt only), checked against
# vkjr2's own device and against the installed `vkjr2 embed` on the same
# frames (with python3); exits 77 (skipped) without the face models.
set -euo pipefail

(($# == 2 || $# == 3)) || { echo "usage: $0 BUILD_DIR SOURCE_DIR [consumer|examples]" >&2; exit 2; }
build="$(cd "$1" && pwd)"
src="$(cd "$2" && pwd)"
what="${3:-consumer}"
[[ "$what" == consumer || "$what" == examples ]] || { echo "unknown project '$what'" >&2; exit 2; }
photo="${VKJR2_CACHE_DIR:-$HOME/.cache/vkjr2}/face-api-1.7.15/demo/sample1.jpg"
if [[ "$what" == examples && ! -f "$photo" ]]; then
  echo "skipped: $photo is missing (scripts/setup fetches the face models)"
  exit 77
fi
cache="$build/CMakeCache.txt"
[[ -f "$cache" ]] || { echo "$build is not a configured build (no CMakeCache.txt)" >&2; exit 2; }

cache_get() { sed -n "s/^$1:[A-Z]*=//p" "$cache" | head -n1; }

tmp="$(mktemp -d "${TMPDIR:-/tmp}/vkjr2-package.XXXXXX")"
trap 'rm -rf "$tmp"' EXIT

echo "-- installing $build into $tmp/prefix"
cmake --install "$build" --prefix "$tmp/prefix" >"$tmp/install.log" ||
  { cat "$tmp/install.log"; exit 1; }

# Configures, builds and checks that vkjr2 came from the prefix: project SOURCE BUILD
configure_and_build() {
  local args=(
  -S "$1" -B "$2"
  -G "$(cache_get CMAKE_GENERATOR)"
  -DCMAKE_CXX_COMPILER="$(cache_get CMAKE_CXX_COMPILER)"
  -DCMAKE_BUILD_TYPE="$(cache_get CMAKE_BUILD_TYPE)"
  -DCMAKE_PREFIX_PATH="$tmp/prefix"
  -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF
  )
  if [[ "$(cache_get VKJR2_SANITIZE)" == ON ]]; then
    # A sanitized static libvkjr2 needs the sanitizer runtimes in the consumer.
    local san="-fsanitize=address,undefined -fno-omit-frame-pointer"
    args+=(-DCMAKE_CXX_FLAGS="$san" -DCMAKE_EXE_LINKER_FLAGS="$san")
  fi
  echo "-- configuring $1"
  cmake "${args[@]}" >"$tmp/configure.log" || { cat "$tmp/configure.log"; exit 1; }
  grep -q "vkjr2_DIR:PATH=$tmp/prefix/" "$2/CMakeCache.txt" ||
    { echo "vkjr2 was not found in the install prefix:" >&2; grep vkjr2_DIR "$2/CMakeCache.txt" >&2; exit 1; }
  echo "-- building $1"
  cmake --build "$2" >"$tmp/build.log" || { cat "$tmp/build.log"; exit 1; }
}

# ASan/UBSan still check the runs; leak checking is the test suite's job
# (with tests/support/lsan.supp for the Vulkan driver's own leaks).
if [[ "$(cache_get VKJR2_SANITIZE)" == ON ]]; then
  export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0"
fi

if [[ "$what" == consumer ]]; then
  configure_and_build "$src/tests/package/consumer" "$tmp/build"
  echo "-- running the consumer"
  "$tmp/build/consumer"
  exit 0
fi

# The examples, as a user would run them from the installed package.
export VKJR2_ARTIFACT_DIR="$tmp/prefix/share/vkjr2"  # the installed blur model
configure_and_build "$src/examples/minimal" "$tmp/minimal"
configure_and_build "$src/examples/host_pipeline" "$tmp/host_pipeline"
echo "-- running examples/minimal on $photo"
"$tmp/minimal/vkjr2_minimal" "$photo" --max-side 640 --preset weak
echo "-- making a 3-frame clip from it (vkjr2 simulate, tilt only)"
"$tmp/prefix/bin/vkjr2" simulate "$photo" "$tmp/clip.avi" --frames 3 --preset weak --no-blur --quiet
echo "-- running examples/host_pipeline on it"
mkdir "$tmp/frames"
"$tmp/host_pipeline/vkjr2_host_pipeline" "$tmp/clip.avi" --max-frames 3 --check --save "$tmp/frames"
echo "-- the same frames through the installed CLI: vkjr2 embed --json"
"$tmp/prefix/bin/vkjr2" embed "$tmp/frames"/frame_{0,1,2}.npy --json >"$tmp/cli.json"
if ! command -v python3 >/dev/null; then
  echo "no python3: the descriptor comparison with the CLI is skipped"
  exit 0
fi
python3 - "$tmp/cli.json" "$tmp/frames" <<'PY'
import json, sys
cli = json.load(open(sys.argv[1]))
worst = 0.0
for i, entry in enumerate(cli):
    host = [[float(v) for v in line.split()] for line in open(f"{sys.argv[2]}/frame_{i}.txt") if line.strip()]
    ref = [face["descriptor"] for face in entry["faces"]]
    if len(host) != len(ref):
        sys.exit(f"frame {i}: host pipeline found {len(host)} face(s), vkjr2 embed {len(ref)}")
    for a, b in zip(host, ref):
        worst = max([worst] + [abs(x - y) for x, y in zip(a, b)])
print(f"host pipeline vs vkjr2 embed: {len(cli)} frame(s), max |descriptor difference| {worst:.3g}")
sys.exit(0 if worst <= 1e-4 else f"descriptors differ by {worst:.3g} > 1e-4")
PY
