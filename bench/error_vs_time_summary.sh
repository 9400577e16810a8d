#!/bin/bash
# The equal-time summary tables of docs/error-vs-time.md, made from the
# committed study results (one results.json per scene) by
# `totalgrad study summary` (core/study/equal_time.h):
#   docs/error-vs-time/summary.md    the Markdown tables the doc shows
#   docs/error-vs-time/summary.json  the same numbers as JSON
#
# Usage: bench/error_vs_time_summary.sh TOTALGRAD [--check]
#   TOTALGRAD  the totalgrad binary (e.g. build/client/totalgrad)
#   --check    write nothing; exit 1 if the committed files differ from what
#              the command prints now (the CTest client_error_vs_time_summary)
set -euo pipefail
if [[ $# -lt 1 ]]; then
  echo "usage: $0 TOTALGRAD [--check]" >&2
  exit 2
fi
bin=$1
check=${2:-}
docs=$(cd "$(dirname "$0")/../docs/error-vs-time" && pwd)
# Label=results, in the doc's order. The cart-pole's is the study of the
# doc's first section (docs/error-vs-time/results.json).
studies=(
  "cart-pole swing-up=$docs/results.json"
  "pendulum=$docs/pendulum/results.json"
  "cart-double-pendulum=$docs/cart-double-pendulum/results.json"
  "pendubot=$docs/pendubot/results.json"
  "double pendulum=$docs/double-pendulum/results.json"
)
markdown=$("$bin" study summary "${studies[@]}" --format markdown)
json=$("$bin" study summary "${studies[@]}" --format json)
if [[ "$check" == "--check" ]]; then
  status=0
  diff <(printf '%s\n' "$markdown") "$docs/summary.md" || status=1
  diff <(printf '%s\n' "$json") "$docs/summary.json" || status=1
  if [[ $status -ne 0 ]]; then
    echo "docs/error-vs-time/summary.{md,json} are not what \`study summary\` prints; rerun $0" >&2
  fi
  exit $status
fi
printf '%s\n' "$markdown" > "$docs/summary.md"
printf '%s\n' "$json" > "$docs/summary.json"
echo "wrote $docs/summary.md and $docs/summary.json"
