#!/bin/bash
# Regenerates issue 16's evidence from the coordinator that runs the sweeps:
# the archives (results export -f json), the per-method tables (report.py),
# the paired comparisons (results compare) and the learning curves
# (results curves --plot). Writes into this directory; docs/results/table1.md
# quotes the outputs.
#
#   make_report.sh BIN_DIR [COORDINATOR]
#
# BIN_DIR holds the totalgrad CLI of the build the coordinator runs (an older
# build's CLI cannot read a newer schema, and the other way round);
# COORDINATOR defaults to 127.0.0.1:7171 (plaintext, loopback), the user
# token comes from TOTALGRAD_TOKEN_FILE.
set -euo pipefail
bin=${1:?usage: make_report.sh BIN_DIR [COORDINATOR]}
coordinator=${2:-127.0.0.1:7171}
here=$(cd "$(dirname "$0")" && pwd)
cli() { "$bin/totalgrad" "$@" --coordinator "$coordinator" --insecure; }
for sweep in table1-tip-k1 balance-del; do
  cli results export "$sweep" -f json -o "$here/$sweep.archive.json"
  # A sweep with no completed trial yet has nothing to compare or plot: say
  # so in the file instead of stopping.
  cli results compare "$sweep" > "$here/$sweep.compare.txt" 2>&1 || true
  cli results curves "$sweep" --plot "$here/$sweep.curves.svg" > "$here/$sweep.curves.txt" 2>&1 || true
done
cli results compare balance-del --baseline DEL > "$here/balance-del.compare-vs-DEL.txt" 2>&1 || true
/usr/bin/python3 "$here/report.py" --totalgrad "$bin/totalgrad" \
  "$here/table1-tip-k1.archive.json" "$here/balance-del.archive.json" > "$here/report.md"
echo "written: $here/{*.archive.json,*.compare*.txt,*.curves.{svg,txt},report.md}"
