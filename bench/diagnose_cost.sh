#!/usr/bin/env bash
# `forcemap diagnose` timed at a base commit and at this checkout, back to back on the same table (the
# base installed from a worktree into a venv of its own; this checkout's `forcemap` from PATH).
#   bench/diagnose_cost.sh DIR BASE TABLE TARGET   -> DIR/base, DIR/base-venv, DIR/{base,head}.{out,err}
set -euo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
dir=${1:?usage: bench/diagnose_cost.sh DIR BASE TABLE TARGET}
base=${2:?usage: bench/diagnose_cost.sh DIR BASE TABLE TARGET}
table=${3:?usage: bench/diagnose_cost.sh DIR BASE TABLE TARGET}
target=${4:?usage: bench/diagnose_cost.sh DIR BASE TABLE TARGET}
if [ -e "$dir" ]; then
  echo "$dir exists: give a new folder" >&2
  exit 2
fi
mkdir -p "$dir"
git -C "$repo" worktree add -q --detach "$dir/base" "$base"
trap 'git -C "$repo" worktree remove --force "$dir/base"' EXIT
python3 -m venv "$dir/base-venv"
"$dir/base-venv/bin/python" -m pip install -q "$dir/base" > "$dir/base-install.log" 2>&1
for side in base head; do
  exe=forcemap
  [ "$side" = base ] && exe="$dir/base-venv/bin/forcemap"
  set +e
  /usr/bin/time -f "$side ($target): %U s CPU, %e s wall" "$exe" diagnose "$table" --target "$target" \
    > "$dir/$side.out" 2> "$dir/$side.err"
  echo "$side rc $?" >> "$dir/$side.err"
  set -e
  tail -2 "$dir/$side.err"
done
