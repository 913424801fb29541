#!/usr/bin/env bash
# The installed package as another project sees it: `cmake --install` of a build tree into a
# fresh prefix, then the consumer project (consumer/) configured against it with
# find_package(genscene), built and run. Exits non-zero, naming the step, when a step fails.
# ctest runs it (tests/install/CMakeLists.txt) with the build tree's compiler and flags:
#   run_install_test.sh build_dir=DIR work_dir=DIR generator=G build_type=T cxx=COMPILER \
#     launcher=CCACHE_OR_EMPTY cxx_flags=FLAGS linker_flags=FLAGS
set -euo pipefail
build_dir="" work_dir="" generator=Ninja build_type=Release cxx=c++ launcher="" cxx_flags="" linker_flags=""
for arg in "$@"; do
  case "$arg" in
    build_dir=* | work_dir=* | generator=* | build_type=* | cxx=* | launcher=* | cxx_flags=* | linker_flags=*)
      printf -v "${arg%%=*}" '%s' "${arg#*=}" ;;
    *) echo "install test: error: unknown argument '$arg' (see the header of $0)" >&2; exit 2 ;;
  esac
done
if [ -z "$build_dir" ] || [ -z "$work_dir" ]; then
  echo "install test: error: build_dir=DIR and work_dir=DIR are required (see the header of $0)" >&2
  exit 2
fi
consumer_src="$(cd "$(dirname "$0")" && pwd)/consumer"
prefix="$work_dir/prefix"
step() { echo "install test: $(date +%T) $*"; }
fail() { echo "install test: error: $*" >&2; exit 1; }

rm -rf "$work_dir"
mkdir -p "$work_dir"

step "cmake --install $build_dir --prefix $prefix"
cmake --install "$build_dir" --prefix "$prefix" >"$work_dir/install.log" 2>&1 ||
  { cat "$work_dir/install.log" >&2; fail "cmake --install failed (is every app and library built?)"; }
for f in lib/cmake/genscene/genscene-config.cmake lib/cmake/genscene/genscene-config-version.cmake \
  lib/cmake/genscene/genscene-targets.cmake lib/libgenscene_fusion.a \
  include/genscene/fusion/kinect_fusion.h bin/genscene; do
  [ -e "$prefix/$f" ] || fail "cmake --install did not install $f"
done

step "configuring the consumer with -DCMAKE_PREFIX_PATH=$prefix (build type $build_type)"
cmake -S "$consumer_src" -B "$work_dir/consumer" -G "$generator" -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_BUILD_TYPE="$build_type" -DCMAKE_CXX_COMPILER="$cxx" \
  -DCMAKE_CXX_COMPILER_LAUNCHER="$launcher" -DCMAKE_CXX_FLAGS="$cxx_flags" \
  -DCMAKE_EXE_LINKER_FLAGS="$linker_flags" >"$work_dir/configure.log" 2>&1 ||
  { cat "$work_dir/configure.log" >&2; fail "the consumer does not configure against $prefix"; }

step "building the consumer (flags: $cxx_flags)"
cmake --build "$work_dir/consumer" -j 1 >"$work_dir/build.log" 2>&1 ||
  { cat "$work_dir/build.log" >&2; fail "the consumer does not compile or link against $prefix"; }

step "running the consumer"
"$work_dir/consumer/consumer" || fail "the consumer ran and failed (exit status $?)"
step "passed"
