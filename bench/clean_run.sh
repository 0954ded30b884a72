#!/usr/bin/env bash
# The README's commands as a new user and CI run them: a fresh clone of this checkout's HEAD, a fresh venv,
# then the test command (`.ci/run`, the install included, with --cpu-top's table and each worker's
# timeline added) or, with `demo`, the first command (`pip install . && forcemap demo` in an empty folder).
#   bench/clean_run.sh DIR [demo]   -> DIR/clone, DIR/venv, DIR/log (the commit, the output, its time);
#                                      with demo also DIR/run (the demo's output) and DIR/install.log
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
dir=${1:?usage: bench/clean_run.sh DIR [demo] (DIR a new folder)}
mode=${2:-tests}
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
if [ "$mode" = demo ]; then
  mkdir "$dir/run"
  (cd "$dir/clone" && . ../venv/bin/activate && python3 -m pip install -q . > ../install.log 2>&1 \
    && cd ../run && /usr/bin/time -f "demo: %e s wall, %U s CPU" forcemap demo) >> "$dir/log" 2>&1
else
  (cd "$dir/clone" && . ../venv/bin/activate && PYTEST_ADDOPTS="--cpu-top ${CPU_TOP:-15}" .ci/run) >> "$dir/log" 2>&1
fi
rc=$?
echo "rc $rc, $(( $(date +%s) - start )) s" >> "$dir/log"
exit $rc
