#!/usr/bin/env bash
# Prints the README's table (case | command | message) from the work folders of a catalogue run:
#   list_messages.sh [WORK_ROOT]     default: build/tests/bad_inputs/work (what ctest -R BadInput uses)
set -euo pipefail
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
ROOT=${1:-$HERE/../../build/tests/bad_inputs/work}
echo "| case | command | message |"
echo "|---|---|---|"
for dir in "$HERE"/cases/*/; do
  name=$(basename "$dir")
  case "$name" in pending_*) continue ;; esac
  cmd=$(grep -v '^[[:space:]]*#' "$dir/cmd" | head -1 | sed 's/\$BIN\///; s/|/\\|/g')
  if [ -f "$ROOT/$name/driver/message" ]; then
    message=$(sed 's/|/\\|/g' "$ROOT/$name/driver/message")
  else
    message="(not run)"
  fi
  printf '| %s | `%s` | `%s` |\n' "$name" "$cmd" "$message"
done
