#!/usr/bin/env bash
# README command 1: installs what is missing, builds, and runs the main job.
#   scripts/run.sh                       -> genscene demo (built-in synthetic scene) into ./genscene-demo
#   scripts/run.sh run --input SRC --out WS [flags]   -> genscene on your recording
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install_deps.sh
scripts/build.sh
if [ $# -eq 0 ]; then
  exec build/apps/genscene demo --out genscene-demo
fi
exec build/apps/genscene "$@"
