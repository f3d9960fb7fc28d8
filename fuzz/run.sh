#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan) and runs each one for
# SECONDS (default 60) from a copy of its seed corpus in fuzz/corpus/NAME/.
# Exits non-zero on any finding (crash, sanitizer report, leak, timeout, an
# allocation above 256 MiB, RSS above 1 GiB); the reproducer is kept under
# BUILD_DIR/findings/.
#   usage: fuzz/run.sh [SECONDS]      env: VKJR2_FUZZ_BUILD_DIR (default build/fuzz)
set -euo pipefail

seconds=${1:-60}
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build=${VKJR2_FUZZ_BUILD_DIR:-$root/build/fuzz}

generator=()
if command -v ninja >/dev/null; then generator=(-G Ninja); fi
cmake -S "$root/fuzz" -B "$build" "${generator[@]}" -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build "$build" -j 1 >/dev/null

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
findings="$build/findings"
mkdir -p "$findings"
status=0
for name in safetensors tfjs npy; do
  cp -r "$root/fuzz/corpus/$name" "$work/$name"
  mkdir -p "$work/artifacts-$name"
  echo "fuzz: $name for ${seconds}s"
  if ! "$build/${name}_fuzz" "$work/$name" -dict="$root/fuzz/$name.dict" \
      -max_total_time="$seconds" -rss_limit_mb=1024 -malloc_limit_mb=256 -timeout=10 \
      -artifact_prefix="$work/artifacts-$name/" -print_final_stats=1 >"$work/$name.log" 2>&1; then
    status=1
    echo "fuzz: $name FOUND A PROBLEM:"
    tail -n 60 "$work/$name.log"
    cp "$work/artifacts-$name"/* "$findings/" 2>/dev/null || true
    echo "fuzz: reproducer(s) in $findings; re-run: $build/${name}_fuzz FILE"
  else
    grep -E "stat::number_of_executed_units|stat::peak_rss_mb" "$work/$name.log" | tr '\n' ' '
    echo
  fi
done
if [ "$status" -eq 0 ]; then echo "fuzz: 3 passed, 0 failed"; else echo "fuzz: findings above"; fi
exit "$status"
