#!/usr/bin/env bash
# Proves find_package(vkjr2) works from an install prefix:
#   run.sh BUILD_DIR SOURCE_DIR
# installs BUILD_DIR into a temporary prefix, configures and builds
# tests/package/consumer against it (CMAKE_PREFIX_PATH only, with the same
# compiler, generator, build type and sanitizers as BUILD_DIR), runs it and
# removes everything it made.
set -euo pipefail

(($# == 2)) || { echo "usage: $0 BUILD_DIR SOURCE_DIR" >&2; exit 2; }
build="$(cd "$1" && pwd)"
src="$(cd "$2" && pwd)"
cache="$build/CMakeCache.txt"
[[ -f "$cache" ]] || { echo "$build is not a configured build (no CMakeCache.txt)" >&2; exit 2; }

cache_get() { sed -n "s/^$1:[A-Z]*=//p" "$cache" | head -n1; }

tmp="$(mktemp -d "${TMPDIR:-/tmp}/vkjr2-package.XXXXXX")"
trap 'rm -rf "$tmp"' EXIT

echo "-- installing $build into $tmp/prefix"
cmake --install "$build" --prefix "$tmp/prefix" >"$tmp/install.log" ||
  { cat "$tmp/install.log"; exit 1; }

args=(
  -S "$src/tests/package/consumer" -B "$tmp/build"
  -G "$(cache_get CMAKE_GENERATOR)"
  -DCMAKE_CXX_COMPILER="$(cache_get CMAKE_CXX_COMPILER)"
  -DCMAKE_BUILD_TYPE="$(cache_get CMAKE_BUILD_TYPE)"
  -DCMAKE_PREFIX_PATH="$tmp/prefix"
  -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF
)
if [[ "$(cache_get VKJR2_SANITIZE)" == ON ]]; then
  # A sanitized static libvkjr2 needs the sanitizer runtimes in the consumer.
  san="-fsanitize=address,undefined -fno-omit-frame-pointer"
  args+=(-DCMAKE_CXX_FLAGS="$san" -DCMAKE_EXE_LINKER_FLAGS="$san")
fi

echo "-- configuring the consumer"
cmake "${args[@]}" >"$tmp/configure.log" || { cat "$tmp/configure.log"; exit 1; }
grep -q "vkjr2_DIR:PATH=$tmp/prefix/" "$tmp/build/CMakeCache.txt" ||
  { echo "vkjr2 was not found in the install prefix:" >&2; grep vkjr2_DIR "$tmp/build/CMakeCache.txt" >&2; exit 1; }
echo "-- building the consumer"
cmake --build "$tmp/build" >"$tmp/build.log" || { cat "$tmp/build.log"; exit 1; }
echo "-- running the consumer"
if [[ "$(cache_get VKJR2_SANITIZE)" == ON ]]; then
  # ASan/UBSan still check the run; leak checking is the test suite's job
  # (with tests/support/lsan.supp for the Vulkan driver's own leaks).
  ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}detect_leaks=0" "$tmp/build/consumer"
else
  "$tmp/build/consumer"
fi
