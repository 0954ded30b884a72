#!/usr/bin/env bash
# Every command a user runs, on every real log of tests/data/real (or the FILEs given): import, export,
# check, fit with a tide and a seiche on the current's speed and direction, grid, diagnose of depth and
# current, report. One line per command: its exit code and the first line it printed that names forcemap
# or an error. A crash shows as rc 1 with "Traceback"; a log that lacks what a command needs should give
# rc 2 with one clear line. bench/RESULTS.md and the closing notes cite its findings.
#   bench/sweep_real_logs.sh DIR [FILE ...]   -> DIR/*.txt (each command's output), DIR/sweep.log
set -uo pipefail
repo=$(cd "$(dirname "$0")/.." && pwd)
dir=${1:?usage: bench/sweep_real_logs.sh DIR [FILE ...] (a new folder)}
shift
if [ -e "$dir" ]; then
  echo "$dir exists: give a new folder" >&2
  exit 2
fi
files=()
for f in "$@"; do files+=("$(realpath "$f")"); done
mkdir -p "$dir" && cd "$dir" || exit 2
R="$repo/tests/data/real"
if [ ${#files[@]} -eq 0 ]; then
  shopt -s nullglob
  files=("$R"/nmea/*.log "$R"/nmea/*.txt "$R"/nmea/irene/*.nmea "$R"/nmea/sfbay/*.gz \
         "$R"/mavlink/*.tlog "$R"/mavlink/*.BIN "$R"/adcp/*.PD0 "$R"/adcp/*.000)
fi
run() {  # run NAME COMMAND...: the command's output to $b.NAME.txt, a line to the log
  local name=$1
  shift
  "$@" > "$b.$name.txt" 2>&1
  local rc=$?
  echo "$b $name rc $rc: $(grep -h '^forcemap\|Traceback\|Error' "$b.$name.txt" | head -1 | cut -c1-220)"
}
for f in "${files[@]}"; do
  b=$(basename "$f" | tr '.' '_')
  run import forcemap import "$f" -o "$b.mcap"
  run export forcemap export "$b.mcap" -o "$b.csv"
  [ -s "$b.csv" ] || continue
  run check forcemap check "$b.csv"
  for tgt in current_speed current_dir; do
    for eff in tide seiche; do
      run "fit-$tgt-$eff" forcemap fit "$b.csv" --target "$tgt" --effects "$eff" --quiet --no-plots
    done
  done
  run fit-depth forcemap fit "$b.csv" --target depth --quiet --no-plots
  run grid-depth forcemap grid "$b.csv" --target depth -o "$b.depth.tif"
  run grid-current forcemap grid "$b.csv" --target current_speed -o "$b.current.nc"
  run diagnose-depth forcemap diagnose "$b.csv" --target depth --rounds 1 --quiet
  run diagnose-current forcemap diagnose "$b.csv" --target current_speed --rounds 1 --quiet
  run report forcemap report "$b.csv" -o "$b.html"
done | tee sweep.log
