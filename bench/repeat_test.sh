#!/usr/bin/env bash
# One test, run again and again in fresh processes, to catch what fails once in tens of runs (the live
# view's spec client stalled once in 22: bench/RESULTS.md). Stops at the first failure and keeps its
# output; BUSY=N runs N busy loops beside it, for a loaded machine.
#   bench/repeat_test.sh DIR N PYTEST_NODE_OR_-k_ARGS...   -> DIR/run<i>.log, DIR/summary
set -uo pipefail
dir=${1:?usage: bench/repeat_test.sh DIR N TEST...}
n=${2:?usage: bench/repeat_test.sh DIR N TEST...}
shift 2
if [ -e "$dir" ]; then
  echo "$dir exists: give a new folder" >&2
  exit 2
fi
mkdir -p "$dir"
pids=()
for _ in $(seq 1 "${BUSY:-0}"); do
  (while :; do :; done) &
  pids+=($!)
done
trap '[ ${#pids[@]} -gt 0 ] && kill "${pids[@]}" 2>/dev/null' EXIT
failed=0
for i in $(seq 1 "$n"); do
  python -m pytest -q -x -p no:cacheprovider "$@" > "$dir/run$i.log" 2>&1
  rc=$?
  echo "run $i rc $rc" >> "$dir/summary"
  if [ $rc -ne 0 ]; then
    failed=1
    break
  fi
done
echo "$(grep -c 'rc 0' "$dir/summary") of $(wc -l < "$dir/summary") runs passed" | tee -a "$dir/summary"
exit $failed
