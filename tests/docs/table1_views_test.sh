#!/bin/bash
# docs/results/table1/issue25-{grid,sensitivity,comparisons}.txt are what
# `results table1` prints from the committed archives alone (issue 25:
# importing the archives reproduces table1.md's grid): imports
# table1-tip-k1, table1-tip-k001 and table1-tip-k1-rest into a new database
# file and compares each view with the committed file, byte for byte.
#
#   table1_views_test.sh TOTALGRAD_CLI [--write]
#
# --write regenerates the three files from the archives (after an export
# that moved a number; then update table1.md's section with them).
set -euo pipefail
cli=${1:?usage: table1_views_test.sh TOTALGRAD_CLI [--write]}
write=${2:-}
here=$(cd "$(dirname "$0")/../../docs/results/table1" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sweeps=(table1-tip-k1 table1-tip-k001 table1-tip-k1-rest)
for sweep in "${sweeps[@]}"; do
  "$cli" results import "$here/$sweep.archive.json" --db "$work/t1.db" > /dev/null
done
status=0
for view in grid sensitivity comparisons; do
  "$cli" results table1 "${sweeps[@]}" --view "$view" --db "$work/t1.db" \
      > "$work/$view.txt"
  if [ "$write" = --write ]; then
    cp "$work/$view.txt" "$here/issue25-$view.txt"
    date -u > "$here/issue25-views-date.txt"
    continue
  fi
  if ! diff -u "$here/issue25-$view.txt" "$work/$view.txt"; then
    echo "FAIL: issue25-$view.txt is not what the committed archives give (above: - file," \
         "+ archives); regenerate with: $0 $cli --write"
    status=1
  fi
done
[ $status -eq 0 ] && echo "the grid, sensitivity and comparisons recompute from the archives"
exit $status
