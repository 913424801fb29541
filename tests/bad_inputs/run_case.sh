#!/usr/bin/env bash
# Runs one case of the bad-input catalogue and checks the README's contract for bad
# input: one clear error line, a non-zero exit, no crash, no hang, no partial output.
#
#   run_case.sh CASE_DIR BIN_DIR WORK_DIR
#
# CASE_DIR holds:
#   cmd           the command line (bash syntax, one line; lines starting with # are ignored).
#                 $BIN is BIN_DIR (the built apps), $CASE is CASE_DIR (committed inputs), $WORK is
#                 the case's fresh work folder, which is also the current directory; $FIX is
#                 tests/bad_inputs/fixtures (small good inputs that setups copy and corrupt).
#   expect        an extended regex (grep -E) that the error message must match. The message is
#                 the text from "<app>: error:" to the end of its stderr line.
#   setup         optional bash script run first in $WORK (set -e; lib.sh sourced: synth_seq,
#                 fused_ws, chain_ws, make_exr, patch, ...) to make the inputs, e.g. by corrupting
#                 good outputs of the apps. Retried twice (from an empty $WORK) if it fails.
#   no_output     optional: paths relative to $WORK that must not exist afterwards, one a line.
#   allow_stderr  optional: extended regexes (one a line) for other stderr lines this case may
#                 print besides the error line (progress lines and warnings are always allowed).
#   allow_files   optional: extended regexes (one a line) for paths relative to $WORK (no ./)
#                 that a failed run may create, e.g. a log that records the error.
#   resource_lock optional: a CTest RESOURCE_LOCK name (read by CMakeLists.txt only).
#
# The case passes when: the exit code is non-zero, not 124/137 (timeout) and below 126 (no crash,
# no signal, the program could run); stderr has exactly one line containing "error:", and that
# message matches `expect`; stderr holds no sanitizer report and no line other than the error,
# progress lines, warnings and `allow_stderr`; no file in $WORK appeared or changed (snapshot of
# every file's size and modification time before and after; `allow_files` excepted), and no
# `no_output` path exists.
# New folders (apps create a workspace folder before they read their inputs) are reported as
# a note, not a failure. Needs bash, coreutils, grep, sed and find only (no python).
set -uo pipefail

if [ $# -ne 3 ]; then
  echo "usage: run_case.sh CASE_DIR BIN_DIR WORK_DIR" >&2
  exit 2
fi
CASE_DIR=$(cd "$1" && pwd) || { echo "run_case: error: no case folder $1" >&2; exit 2; }
BIN_DIR=$(cd "$2" && pwd) || { echo "run_case: error: no bin folder $2" >&2; exit 2; }
ROOT=$3
NAME=$(basename "$CASE_DIR")
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
TIMEOUT=${BAD_INPUT_TIMEOUT:-60}

fail() {
  echo "FAIL: $NAME: $*"
  if [ -s "$ROOT/driver/stderr" ]; then
    echo "---- stderr ----"
    tr '\r' '\n' < "$ROOT/driver/stderr" | head -40
    echo "----------------"
  fi
  echo "command: $CMD"
  exit 1
}

[ -f "$CASE_DIR/cmd" ] || { echo "FAIL: $NAME: no cmd file"; exit 1; }
[ -f "$CASE_DIR/expect" ] || { echo "FAIL: $NAME: no expect file"; exit 1; }
CMD=$(grep -v '^[[:space:]]*#' "$CASE_DIR/cmd" | grep -v '^[[:space:]]*$')
[ "$(printf '%s\n' "$CMD" | wc -l)" -eq 1 ] || { echo "FAIL: $NAME: cmd must hold one command line"; exit 1; }
EXPECT=$(grep -v '^[[:space:]]*$' "$CASE_DIR/expect" | head -1)

# A fresh work folder; only ever delete one this script made (it holds the marker).
case "$ROOT" in
  "" | "/" | "$HOME" | "$CASE_DIR"*) echo "FAIL: $NAME: refusing work folder '$ROOT'"; exit 1 ;;
esac
if [ -e "$ROOT" ]; then
  if [ -f "$ROOT/.bad-input-work" ]; then
    rm -rf "$ROOT"
  elif [ -n "$(ls -A "$ROOT" 2>/dev/null)" ]; then
    echo "FAIL: $NAME: work folder $ROOT exists and was not made by run_case.sh"
    exit 1
  fi
fi
mkdir -p "$ROOT/work" "$ROOT/driver" && touch "$ROOT/.bad-input-work" || { echo "FAIL: $NAME: cannot make $ROOT"; exit 1; }
WORK=$(cd "$ROOT/work" && pwd)
export BIN="$BIN_DIR" CASE="$CASE_DIR" WORK FIX="$HERE/fixtures"
# Sanitizer builds: report and stop at the first problem (scripts/test.sh sets the same).
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:intercept_tls_get_addr=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}

# Apps may be relinked while the catalogue runs (a developer's build): wait for them.
wait_for_apps() {
  local tries=0 app
  for app in genscene genscene-synth; do
    while [ ! -x "$BIN_DIR/$app" ] && [ $tries -lt 6 ]; do sleep 5; tries=$((tries + 1)); done
  done
}
wait_for_apps

# Runs "$@" under the timeout in $WORK, stdout/stderr to driver/; retries when an app could not
# be executed (126 "text file busy" / 127 "not found" while it is being rebuilt).
run_timed() {
  local attempt rc
  for attempt in 1 2 3; do
    (cd "$WORK" && timeout -k 5 "$TIMEOUT" "$@") > "$ROOT/driver/stdout" 2> "$ROOT/driver/stderr"
    rc=$?
    if { [ $rc -eq 126 ] || [ $rc -eq 127 ]; } &&
       grep -qE 'Text file busy|No such file or directory|cannot execute' "$ROOT/driver/stderr"; then
      sleep 15
      continue
    fi
    break
  done
  return $rc
}

# 1. Setup (retried from an empty work folder: an app it runs may be being relinked).
if [ -f "$CASE_DIR/setup" ]; then
  for attempt in 1 2 3; do
    find "$WORK" -mindepth 1 -delete
    run_timed bash -c 'set -euo pipefail; source "$1"; source "$2"' setup "$HERE/lib.sh" "$CASE_DIR/setup"
    rc=$?
    [ $rc -eq 0 ] && break
    [ $attempt -lt 3 ] && sleep 15
  done
  if [ $rc -ne 0 ]; then
    CMD="(setup) $CASE_DIR/setup"
    fail "setup failed with exit code $rc"
  fi
fi

snapshot() { (cd "$WORK" && find . -mindepth 1 -printf '%y %s %T@ %p\n' | LC_ALL=C sort); }
snapshot > "$ROOT/driver/before"

# 2. The command.
START=$(date +%s%N)
run_timed bash -c "$CMD"
RC=$?
END=$(date +%s%N)
snapshot > "$ROOT/driver/after"
MILLIS=$(((END - START) / 1000000))
printf -v SECONDS_TAKEN "%d.%02d" $((MILLIS / 1000)) $((MILLIS % 1000 / 10))

# 3. Exit code: an error, not a timeout, a crash or a signal.
if [ $RC -eq 0 ]; then fail "exit code 0 (the bad input was accepted)"; fi
if [ $RC -eq 124 ] || [ $RC -eq 137 ]; then fail "timed out after ${TIMEOUT} s (exit code $RC): a hang"; fi
if [ $RC -ge 128 ]; then fail "killed by signal $((RC - 128)) (exit code $RC): a crash"; fi
if [ $RC -ge 126 ]; then fail "exit code $RC: the command could not be run"; fi

# 4. stderr: no sanitizer report; exactly one error line, matching `expect`; nothing foreign.
if grep -qE 'ERROR: (Address|Leak|Memory|Thread)Sanitizer|runtime error:|SUMMARY: [A-Za-z]*Sanitizer' "$ROOT/driver/stderr"; then
  fail "sanitizer report in stderr"
fi
ERROR_LINES=$(grep -c 'error:' "$ROOT/driver/stderr")
if [ "$ERROR_LINES" -ne 1 ]; then fail "$ERROR_LINES stderr lines contain 'error:', expected exactly 1"; fi
ERROR_LINE=$(grep 'error:' "$ROOT/driver/stderr")
MESSAGE=$(printf '%s\n' "$ERROR_LINE" | tr '\r' '\n' | grep 'error:' | grep -oE '[A-Za-z][A-Za-z0-9_-]*: error: .*' | head -1)
[ -n "$MESSAGE" ] || fail "the error line is not '<app>: error: <message>': $ERROR_LINE"
printf '%s\n' "$MESSAGE" > "$ROOT/driver/message"
if ! printf '%s\n' "$MESSAGE" | grep -qE -- "$EXPECT"; then
  fail "the error message does not match expect: $EXPECT"$'\n'"  message: $MESSAGE"
fi

ALLOWED='^(\[[0-9]+/[0-9]+\] [a-z].*|reading frames: [0-9]+(/[0-9]+)?|fusing: [0-9]+(/[0-9]+)? frames, .*|frame [0-9]+ \(t = [^)]*\): .*|synth: rendered [0-9]+/[0-9]+ frames|rendered [0-9]+/[0-9]+ views|capturing from .*|capturing: [0-9]+(/[0-9]+)? frames|[A-Za-z][A-Za-z0-9_-]*: warning: .*)[[:space:]]*$'
EXTRA_ALLOWED=""
if [ -f "$CASE_DIR/allow_stderr" ]; then
  EXTRA_ALLOWED=$(grep -v '^[[:space:]]*$' "$CASE_DIR/allow_stderr" | paste -sd '|')
fi
# Every stderr segment (lines split at \n and \r), the error line's text before "<app>: error:"
# included, must be empty, a progress line, a warning or allowed by the case.
FOREIGN=$(tr '\r' '\n' < "$ROOT/driver/stderr" | sed -E 's/[A-Za-z][A-Za-z0-9_-]*: error: .*$//' |
          grep -vE '^[[:space:]]*$' | grep -vE "$ALLOWED" |
          { if [ -n "$EXTRA_ALLOWED" ]; then grep -vE "$EXTRA_ALLOWED"; else cat; fi; } || true)
if [ -n "$FOREIGN" ]; then
  fail "stderr holds lines other than the one error line (library noise or a multi-line error):"$'\n'"$FOREIGN"
fi

# 5. No partial output: no new or changed file anywhere in $WORK, no `no_output` path.
CHANGES=$(LC_ALL=C comm -13 "$ROOT/driver/before" "$ROOT/driver/after" | grep -v '^d ' || true)
if [ -n "$CHANGES" ] && [ -f "$CASE_DIR/allow_files" ]; then
  ALLOWED_FILES=$(grep -v '^[[:space:]]*$' "$CASE_DIR/allow_files" | paste -sd '|')
  CHANGES=$(printf '%s\n' "$CHANGES" | while IFS= read -r line; do
    path=${line#* * * ./}
    printf '%s\n' "$path" | grep -qE -- "$ALLOWED_FILES" || printf '%s\n' "$line"
  done)
fi
if [ -n "$CHANGES" ]; then
  fail "the failed run left files behind (new or changed; type size mtime path):"$'\n'"$CHANGES"
fi
if [ -f "$CASE_DIR/no_output" ]; then
  while IFS= read -r path; do
    [ -z "$path" ] && continue
    case "$path" in \#*) continue ;; esac
    if [ -e "$WORK/$path" ]; then fail "output $path exists after the failed run"; fi
  done < "$CASE_DIR/no_output"
fi
NEW_DIRS=$(LC_ALL=C comm -13 <(sed -nE "s/^d [0-9]+ [0-9.]+ //p" "$ROOT/driver/before" | LC_ALL=C sort) \
                             <(sed -nE "s/^d [0-9]+ [0-9.]+ //p" "$ROOT/driver/after" | LC_ALL=C sort))

echo "PASS: $NAME (exit $RC, ${SECONDS_TAKEN} s): $MESSAGE"
if [ -n "$NEW_DIRS" ]; then
  echo "note: new folders left behind (no unexpected files in them): $(printf "%s " $NEW_DIRS)"
fi
exit 0
