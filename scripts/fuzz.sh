#!/usr/bin/env bash
# Runs the libFuzzer harnesses of fuzz/, two at a time, each for a time budget, on
# seed corpora made by our own writers, small files of ../shared/data and the inputs of
# fuzz/regressions/ (findings of earlier runs, fixed). Needs the fuzz build:
# scripts/build.sh --fuzz (clang; scripts/test.sh does it).
#   scripts/fuzz.sh                 every harness, 30 s each (what CI runs)
#   scripts/fuzz.sh 600 fuzz_ply    one harness for 10 minutes (by hand)
#   GENSCENE_FUZZ_RUNS=1000000 scripts/fuzz.sh 0 fuzz_ply    a number of executions instead
# GENSCENE_FUZZ_TIMEOUT (s, default 10) is the time one input may take; raise it for runs beside
# other work (a starved process is reported as a hang).
# A finding (crash, sanitizer report, uncaught exception, timeout, allocation over the limit)
# fails the run and leaves its input in build-fuzz/fuzz/artifacts/. Corpora grow in
# build-fuzz/fuzz/corpus/ across runs.
set -euo pipefail
cd "$(dirname "$0")/.."
SECONDS_EACH="${1:-30}"
shift || true
BUILD="${GENSCENE_FUZZ_BUILD_DIR:-build-fuzz}"
ALL=(fuzz_png fuzz_exr fuzz_ply fuzz_obj fuzz_mcol fuzz_lights_json fuzz_scene_json fuzz_scene_xml
     fuzz_config fuzz_text_formats fuzz_oni fuzz_tsdf)
HARNESSES=("$@")
[ ${#HARNESSES[@]} -gt 0 ] || HARNESSES=("${ALL[@]}")
SHARED="${GENSCENE_SHARED_DATA:-../shared/data}"
for h in "${HARNESSES[@]}"; do
  if [ ! -x "$BUILD/fuzz/$h" ]; then
    echo "fuzz: error: $BUILD/fuzz/$h is missing (build it: scripts/build.sh --fuzz)" >&2
    exit 1
  fi
done

ROOT="$(cd "$BUILD" && pwd)/fuzz"

# Seeds: our writers' outputs, and the smallest files of each format in ../shared/data.
shared_seeds() {  # harness -> file list
  [ -d "$SHARED" ] || return 0
  case "$1" in
    fuzz_png) find "$SHARED" -name '*.png' -size -20k ;;
    fuzz_exr) find "$SHARED" -name '*.exr' -size -20k ;;
    fuzz_ply) find "$SHARED" -name '*.ply' -size -20k ;;
    fuzz_obj) find "$SHARED" -name '*.obj' -size -20k ;;
    fuzz_scene_xml) find "$SHARED" -name '*.xml' -size -8k ;;
    fuzz_scene_json | fuzz_config | fuzz_lights_json) find "$SHARED" -name '*.json' -size -4k ;;
  esac
}
# intercept_tls_get_addr=0: see scripts/test.sh (a sanitizer runtime bug that kills the leak check).
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:strict_string_checks=1:intercept_tls_get_addr=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export LSAN_OPTIONS="suppressions=$PWD/scripts/lsan.supp:print_suppressions=0"
mkdir -p "$ROOT/artifacts" "$ROOT/logs"
for h in "${HARNESSES[@]}"; do
  seeds="$ROOT/seeds/$h"
  rm -rf "$seeds"
  GENSCENE_FUZZ_SEEDS="$seeds" "$BUILD/fuzz/$h" >/dev/null 2>&1
  n=0
  while IFS= read -r f; do n=$((n + 1)); cp "$f" "$seeds/shared_${n}_$(basename "$f")"; done < <(shared_seeds "$h" | sort)
  # Inputs that once failed (fuzz/regressions/HARNESS/): every run replays them first.
  if [ -d "fuzz/regressions/$h" ]; then cp fuzz/regressions/"$h"/* "$seeds/"; fi
  if [ "$h" = fuzz_text_formats ] && [ -d "$SHARED/cbox-cycles" ]; then
    { printf '\000'; cat "$SHARED/cbox-cycles/poses_train.txt"; } > "$seeds/shared_poses"
    { printf '\002'; cat "$SHARED/cbox-cycles/intrinsics.txt"; } > "$seeds/shared_intrinsics"
    { printf '\004'; cat "$SHARED/cbox-cycles/views/train/rgb.txt"; } > "$seeds/shared_rgb_list"
    { printf '\005'; cat "$SHARED/cbox-cycles/views/train/depth.txt"; } > "$seeds/shared_depth_list"
  fi
  mkdir -p "$ROOT/corpus/$h"
done

run_one() {
  local h="$1" budget
  if [ -n "${GENSCENE_FUZZ_RUNS:-}" ]; then budget="-runs=$GENSCENE_FUZZ_RUNS"; else budget="-max_total_time=$SECONDS_EACH"; fi
  if "$BUILD/fuzz/$h" "$budget" -timeout="${GENSCENE_FUZZ_TIMEOUT:-10}" -rss_limit_mb=2048 -malloc_limit_mb=1024 -max_len=65536 \
       -print_final_stats=1 -artifact_prefix="$ROOT/artifacts/$h-" "$ROOT/corpus/$h" "$ROOT/seeds/$h" \
       > "$ROOT/logs/$h.log" 2>&1; then
    local runs cov
    runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$ROOT/logs/$h.log")
    cov=$(grep -o 'cov: [0-9]*' "$ROOT/logs/$h.log" | tail -1)
    printf 'fuzz: %-18s ok   %9s runs  %s\n' "$h" "$runs" "$cov"
  else
    printf 'fuzz: %-18s FAIL (log: %s)\n' "$h" "$ROOT/logs/$h.log"
    grep -E 'ERROR|SUMMARY|terminate|what\(\)|runtime error|Test unit written' "$ROOT/logs/$h.log" | head -20
    return 1
  fi
}
export -f run_one
export BUILD ROOT SECONDS_EACH
printf '%s\n' "${HARNESSES[@]}" | xargs -P 2 -I{} bash -c 'run_one {}'
