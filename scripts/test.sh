#!/usr/bin/env bash
# README command 2: installs what is missing, checks the formatting, builds, and runs the whole
# test suite: the Release build compiles the apps and benchmarks, the ASan + UBSan build runs every test; then the fuzz
# build (clang) runs every libFuzzer harness of fuzz/ for 30 s (scripts/fuzz.sh). CI (.ci/run)
# calls exactly this.
#   scripts/test.sh            everything (what CI runs)
#   scripts/test.sh --fast     Release build, tests labelled "fast" only (for developers)
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh

if [ "${CI:-}" = "true" ] && [ ! -d ../shared/data ] && [ -z "${GENSCENE_SHARED_DATA:-}" ]; then
  echo "test: error: CI=true but ../shared/data is missing; the data tests must run in CI" >&2
  exit 1
fi

scripts/check_format.sh

if [ "${1:-}" = "--fast" ]; then
  scripts/build.sh
  (cd build && ctest --output-on-failure -j 2 -L fast)
  exit 0
fi
# The Release build makes every app and the benchmarks (CMake target genscene_release_pass: what
# scripts/run.sh and users run compiles); every test runs in the sanitizer pass below.
echo "test: $(date +%T) Release build (apps, benchmarks)"
scripts/build.sh --target genscene_release_pass

# The sanitizer pass: ASan + UBSan at -O2 without GCC's use-after-scope check (see CMakeLists.txt),
# every test: "fast", "apps", "slow" (long renders compared with other renderers, the fusion
# sequences, the whole chain) and "badinput" (the catalogue, 224 runs of the apps).
# At -O1 a 150-frame fusion sequence takes over 10 minutes (70 s at -O2), and the use-after-scope
# check makes genscene-fuse 1.75x slower. Long tests carry a CTest COST so that they start first
# and do not run alone at the end.
echo "test: $(date +%T) sanitizer build (ASan + UBSan)"
scripts/build.sh --sanitize
# intercept_tls_get_addr=0: the __tls_get_addr interceptor of GCC 12's and clang 14's sanitizer
# runtimes (fixed upstream in GCC 14 / LLVM 17) takes a dynamic TLS block whose address is 16
# bytes past a page boundary for a pre-2.25 glibc header and reads a bogus range from before it;
# the leak check's tracer then dies at exit ("Tracer caught signal 11", exit 134) although
# nothing leaked. Dynamic TLS comes from the OpenNI2 drivers that the .oni and camera paths
# dlopen, so it hit those tests at random (seen once in CI, in genscene-fuse on a .oni). Leaks are
# still found; at worst an object held only in such TLS could be reported as a leak.
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1:intercept_tls_get_addr=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export LSAN_OPTIONS="suppressions=$PWD/scripts/lsan.supp:print_suppressions=0"
echo "test: $(date +%T) sanitizer tests (all)"
(cd build-sanitize && ctest --output-on-failure -j 2 --timeout 1200)
echo "test: $(date +%T) fuzz build (clang, ASan + UBSan, libFuzzer)"
scripts/build.sh --fuzz
echo "test: $(date +%T) fuzzing every parser, 30 s each"
scripts/fuzz.sh 30
echo "test: $(date +%T) all passed (Release, ASan + UBSan, fuzzing)"
