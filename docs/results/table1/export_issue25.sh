#!/bin/bash
# Exports issue 25's Table-1 sweeps from the coordinator that runs them into
# this directory, each as an archive with every completed trial's final
# checkpoint (`results export -f json --checkpoints`; format:
# docs/results_schema.md, "Sweep archives"), and prints each sweep's progress
# and results table. Run before every stop; commit what it writes.
#
#   export_issue25.sh BIN_DIR [COORDINATOR]
#
# BIN_DIR holds the CLI of the coordinator's build; COORDINATOR defaults to
# 127.0.0.1:7171 (plaintext, loopback); the user token comes from
# TOTALGRAD_TOKEN_FILE. An archive is written to a temporary name and moved
# into place only when complete.
set -euo pipefail
bin=${1:?usage: export_issue25.sh BIN_DIR [COORDINATOR]}
coordinator=${2:-127.0.0.1:7171}
here=$(cd "$(dirname "$0")" && pwd)
cli() { "$bin/totalgrad" "$@" --coordinator "$coordinator" --insecure; }
for sweep in table1-tip-k001 table1-tip-k1-rest table1-tip-k1-rerun; do
  rm -f "$here/$sweep.archive.json.partial"
  cli results export "$sweep" -f json --checkpoints -o "$here/$sweep.archive.json.partial"
  mv "$here/$sweep.archive.json.partial" "$here/$sweep.archive.json"
  cli sweep status "$sweep" | head -3
  cli results table "$sweep" || true
done
# Issue 27's DEL-against-RP example runs on the same coordinator.
if cli sweep status diag-balance-del-rp > /dev/null 2>&1; then
  diag=$here/../diagnostics/diag-balance-del-rp.archive.json
  rm -f "$diag.partial"
  cli results export diag-balance-del-rp -f json --checkpoints -o "$diag.partial"
  mv "$diag.partial" "$diag"
  cli results table diag-balance-del-rp || true
fi
