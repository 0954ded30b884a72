#!/usr/bin/env bash
# The README's first command as a new user runs it: a fresh clone of this checkout's HEAD, a fresh venv,
# `python3 -m pip install . && forcemap demo` in an empty folder.
#   bench/fresh_demo.sh DIR   -> DIR/clone, DIR/venv, DIR/run (the demo's output), DIR/log (its time, rc)
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
dir=${1:?usage: bench/fresh_demo.sh DIR (a new folder)}
if [ -e "$dir" ]; then
  echo "$dir exists: give a new folder" >&2
  exit 2
fi
mkdir -p "$dir/run"
git clone -q "$repo" "$dir/clone"
python3 -m venv "$dir/venv"
git -C "$dir/clone" log --oneline -1 > "$dir/log"
set +e
(cd "$dir/clone" && . ../venv/bin/activate && python3 -m pip install -q . > ../install.log 2>&1 \
  && cd ../run && /usr/bin/time -f "demo: %e s wall, %U s CPU" forcemap demo) >> "$dir/log" 2>&1
rc=$?
echo "rc $rc" >> "$dir/log"
tail -3 "$dir/log"
exit $rc
