#!/usr/bin/env bash
# Configures and builds genscene (Release, -j2, ccache when available).
#   scripts/build.sh               -> build/
#   scripts/build.sh --sanitize    -> build-sanitize/ (ASan + UBSan, -O2 -g1: the whole test suite
#                                     runs there, -O1 would run it 2-3x slower; function and line
#                                     names in the reports)
#   scripts/build.sh --fuzz        -> build-fuzz/ (clang, ASan + UBSan, -O1 -g1: the parsers and
#                                     the libFuzzer harnesses of fuzz/ only)
# Extra arguments after the options are passed to `cmake --build` (e.g. --target genscene).
set -euo pipefail
cd "$(dirname "$0")/.."

BUILD_DIR=build
CMAKE_ARGS=(-DCMAKE_BUILD_TYPE=Release)
if [ "${1:-}" = "--sanitize" ]; then
  shift
  BUILD_DIR=build-sanitize
  CMAKE_ARGS=(-DCMAKE_BUILD_TYPE=None "-DCMAKE_CXX_FLAGS=-O2 -g1" -DGENSCENE_SANITIZE=ON -DGENSCENE_BUILD_BENCH=OFF)
elif [ "${1:-}" = "--fuzz" ]; then
  shift
  BUILD_DIR=build-fuzz
  CMAKE_ARGS=(-DCMAKE_BUILD_TYPE=None "-DCMAKE_CXX_FLAGS=-O1 -g1" -DGENSCENE_FUZZ_ONLY=ON -DCMAKE_CXX_COMPILER=clang++)
fi
JOBS="${GENSCENE_JOBS:-2}"

# Ninja when installed (scripts/install_deps.sh installs it): on 2 cores it kept both busy (97 %)
# where Make left more idle and spent more CPU on its own bookkeeping (the Release pass target,
# measured back to back: 5:03 with Ninja, 6:02 with Make). A folder already configured keeps its
# generator (CMake refuses to switch).
GENERATOR=()
if [ ! -f "$BUILD_DIR/CMakeCache.txt" ] && command -v ninja >/dev/null 2>&1; then GENERATOR=(-G Ninja); fi

cmake -S . -B "$BUILD_DIR" "${GENERATOR[@]}" "${CMAKE_ARGS[@]}" >/dev/null
cmake --build "$BUILD_DIR" -j "$JOBS" "$@"
