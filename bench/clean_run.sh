#!/usr/bin/env bash
# The README's commands as a new user and CI run them: a fresh clone of this checkout's HEAD, a fresh venv,
# then the test command (`.ci/run`, the install included, with --cpu-top's table and each worker's
# timeline added) or, with `demo`, the first command (`pip install . && forcemap demo` in an empty folder).
#   bench/clean_run.sh DIR [demo [BUSY]] -> DIR/clone, DIR/venv, DIR/log (the commit, the output, its time);
#                                           with demo also DIR/run (the demo's output) and DIR/install.log
# BUSY (demo only, default 0): that many `python3 -c "while True: pass"` loops spin beside the install and
# the demo, killed at the end (issue 58: 2 of them on this 2-core machine). The demo mode ends its log with
#   install N s wall; demo N s wall, N s CPU (user+sys, its subprocesses included); with the install N s; busy B
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
dir=${1:?usage: bench/clean_run.sh DIR [demo [BUSY]] (DIR a new folder)}
mode=${2:-tests}
busy=${3:-0}
if [ -e "$dir" ]; then
  echo "$dir exists: give a new folder" >&2
  exit 2
fi
mkdir -p "$dir"
git clone -q "$repo" "$dir/clone"
python3 -m venv "$dir/venv"
git -C "$dir/clone" log --oneline -1 > "$dir/log"
loops=()
stop_loops() { for p in "${loops[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap stop_loops EXIT
for _ in $(seq 1 "$busy"); do
  python3 -c "while True: pass" &
  loops+=($!)
done
start=$(date +%s%N)
set +e
if [ "$mode" = demo ]; then
  mkdir "$dir/run"
  (cd "$dir/clone" && . ../venv/bin/activate && python3 -m pip install -q . > ../install.log 2>&1) >> "$dir/log" 2>&1
  rc=$?
  installed=$(date +%s%N)
  if [ $rc = 0 ]; then
    (cd "$dir/run" && . ../venv/bin/activate \
      && /usr/bin/time -o ../demo.time -f "%e %U %S" forcemap demo) >> "$dir/log" 2>&1
    rc=$?
    read -r wall user sys < <(tail -1 "$dir/demo.time")
    awk -v i="$(( (installed - start) / 1000000 ))e-3" -v w="$wall" -v u="$user" -v s="$sys" -v b="$busy" \
      'BEGIN { printf "install %.0f s wall; demo %.0f s wall, %.1f s CPU (user+sys, its subprocesses included); with the install %.0f s; busy %d\n", i, w, u + s, i + w, b }' \
      | tee -a "$dir/log"
  fi
else
  (cd "$dir/clone" && . ../venv/bin/activate && PYTEST_ADDOPTS="--cpu-top ${CPU_TOP:-15}" .ci/run) >> "$dir/log" 2>&1
  rc=$?
fi
echo "rc $rc, $(( ($(date +%s%N) - start) / 1000000000 )) s" >> "$dir/log"
exit $rc
