#!/usr/bin/env bash
# The suite as CI runs it: a fresh clone of this checkout's HEAD, a fresh venv, `.ci/run` (the README's
# test command, the install included), with --cpu-top's table and each worker's timeline added.
#   bench/clean_run.sh DIR   -> DIR/clone, DIR/venv, DIR/log (the commit, the run's output, its time)
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
dir=${1:?usage: bench/clean_run.sh DIR (a new folder)}
if [ -e "$dir" ]; then
  echo "$dir exists: give a new folder" >&2
  exit 2
fi
mkdir -p "$dir"
git clone -q "$repo" "$dir/clone"
python3 -m venv "$dir/venv"
git -C "$dir/clone" log --oneline -1 > "$dir/log"
start=$(date +%s)
set +e
(cd "$dir/clone" && . ../venv/bin/activate && PYTEST_ADDOPTS="--cpu-top ${CPU_TOP:-15}" .ci/run) >> "$dir/log" 2>&1
rc=$?
echo "rc $rc, $(( $(date +%s) - start )) s" >> "$dir/log"
exit $rc
