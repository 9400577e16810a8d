#!/usr/bin/env bash
# bench/torch_rp_iteration.py (the PyTorch peer of `totalgrad bench iteration`,
# issue 11) must compute the same RP iteration as ours: J and the gradient
# within 1e-8 relative, on a dump from `totalgrad bench dump-iteration`.
# Two negative controls show that the check can fail: a gradient component of
# ours off by 1e-6 relative, and the dump's normals of two steps swapped (the
# script must use the dumped random numbers, not its own).
#
# Usage: torch_rp_agreement_test.sh TOTALGRAD_BINARY SCRIPT PYTHON
set -euo pipefail
totalgrad="$1"
script="$2"
python="$3"

if ! "$python" -c 'import torch' 2>/dev/null; then
  echo "FAIL: $python cannot import torch; install python3-torch (deploy/install-deps.sh)" >&2
  exit 1
fi

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

"$totalgrad" bench dump-iteration --data 40 --particles 20 --horizon 5 --out "$work/dump.json"

echo "== agreement (must pass)"
"$python" "$script" "$work/dump.json" --check-only

"$python" - "$work/dump.json" "$work/gradient_off.json" "$work/normals_swapped.json" <<'EOF'
import json, sys
source, gradient_off, normals_swapped = sys.argv[1:]
with open(source) as f:
    doc = json.load(f)
# The gradient's largest component, so that the change is >= 1e-6 / sqrt(254)
# of the gradient's norm: far above the 1e-8 tolerance.
gradient = doc["gradient"]
entries = [(row, k) for row in gradient["centres"] for k in range(len(row))]
entries += [(gradient[part], k) for part in ("log_lengthscales", "weights")
            for k in range(len(gradient[part]))]
row, k = max(entries, key=lambda entry: abs(entry[0][entry[1]]))
original = row[k]
row[k] = original * (1 + 1e-6)
with open(gradient_off, "w") as f:
    json.dump(doc, f)
row[k] = original
eps = doc["normals"]["eps"]
eps[0], eps[1] = eps[1], eps[0]
with open(normals_swapped, "w") as f:
    json.dump(doc, f)
EOF

for control in gradient_off normals_swapped; do
  echo "== negative control $control (must be rejected)"
  if "$python" "$script" "$work/$control.json" --check-only >/dev/null 2>"$work/$control.err"; then
    echo "FAIL: the check accepted the $control dump" >&2
    exit 1
  fi
  if ! grep -q DISAGREEMENT "$work/$control.err"; then
    echo "FAIL: $control was rejected for another reason than a disagreement:" >&2
    cat "$work/$control.err" >&2
    exit 1
  fi
done
echo "PASS"
