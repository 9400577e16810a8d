#!/bin/bash
# Paired before/after timing of one `totalgrad bench` command on two builds:
# runs the command PAIRS times on each build, alternating which build goes
# first (ABBA...) so that a change in the machine's load hits both alike, and
# prints one JSON object: each build's median CPU seconds per iteration, the
# median of the per-pair ratios after / before, and every run's number.
#
#   bench/paired_before_after.sh BEFORE_BIN AFTER_BIN PAIRS bench iteration --data 450 --repeats 5
#   KEY=extrapolated_cpu_seconds bench/paired_before_after.sh B A 3 bench trial --method RP --seed 5
#
# The command must print a JSON object with the number KEY (default
# "cpu_seconds_per_iteration", which `bench iteration` prints). Exit 2 on bad
# usage, 1 when a run fails.
set -euo pipefail
if [[ $# -lt 5 ]]; then
  echo "usage: $0 BEFORE_BIN AFTER_BIN PAIRS bench SUBCOMMAND [ARGS...]" >&2
  exit 2
fi
before=$1 after=$2 pairs=$3
export KEY=${KEY:-cpu_seconds_per_iteration}
shift 3
for bin in "$before" "$after"; do
  [[ -x $bin ]] || { echo "$0: '$bin' is not an executable" >&2; exit 2; }
done
[[ $pairs =~ ^[1-9][0-9]*$ ]] || { echo "$0: PAIRS '$pairs' is not a positive integer" >&2; exit 2; }

runs=$(mktemp)
trap 'rm -f "$runs"' EXIT
run() {  # run LABEL BIN
  local out
  out=$("$2" "${@:3}" 2>/dev/null) || { echo "$0: $1 build failed: $2 ${*:3}" >&2; exit 1; }
  printf '%s\t%s\n' "$1" "$(printf '%s' "$out" | /usr/bin/python3 -c \
    'import json,os,sys; print(json.load(sys.stdin)[os.environ["KEY"]])')" >> "$runs"
}
for ((i = 0; i < pairs; ++i)); do
  if ((i % 2 == 0)); then
    run before "$before" "$@"; run after "$after" "$@"
  else
    run after "$after" "$@"; run before "$before" "$@"
  fi
done
/usr/bin/python3 - "$runs" "$*" <<'PY'
import json, os, statistics, sys
rows = [line.split("\t") for line in open(sys.argv[1]).read().split("\n") if line]
before = [float(v) for k, v in rows if k == "before"]
after = [float(v) for k, v in rows if k == "after"]
ratios = [a / b for a, b in zip(after, before)]
print(json.dumps({
    "command": sys.argv[2], "key": os.environ["KEY"], "pairs": len(ratios),
    "before_median": statistics.median(before),
    "after_median": statistics.median(after),
    "after_over_before_median_of_pairs": statistics.median(ratios),
    "before": before, "after": after}, indent=1))
PY
