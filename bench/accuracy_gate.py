#!/usr/bin/env python3
"""Accuracy gate of a fast computation path (docs/results/speed.md).

    accuracy_gate.py FAST.json EXACT.json [--threshold 0.01]

Both files come from `totalgrad bench gradients` with the same snapshot,
episode, method, particles, horizon, replicates and seed, i.e. common random
numbers: replicate r of both runs drew the same random numbers, so any
difference between g_fast[r] and g_exact[r] is the computation's.

Reports, for the R replicates:
  deviation  = mean_r ||g_fast[r] - g_exact[r]|| / ||g_exact[r]||
  rel_se     = sqrt(mean_r ||g_exact[r] - mean g_exact||^2) / ||mean g_exact||,
               the estimator's relative Monte Carlo standard error at this P
  ratio      = deviation / rel_se
and passes when ratio < threshold (1 %). Prints one JSON object; exit code
0 = pass, 1 = fail, 2 = the two files are not comparable.
"""
import argparse
import json
import math
import sys


def norm(v):
    return math.sqrt(sum(x * x for x in v))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("fast")
    parser.add_argument("exact")
    parser.add_argument("--threshold", type=float, default=0.01)
    args = parser.parse_args()
    with open(args.fast) as f:
        fast = json.load(f)
    with open(args.exact) as f:
        exact = json.load(f)
    for key in ("episode", "policy", "method", "particles", "horizon", "replicates", "seed"):
        if fast.get(key) != exact.get(key):
            print(f"accuracy_gate: '{key}' differs ({fast.get(key)!r} vs {exact.get(key)!r}): "
                  "not common random numbers", file=sys.stderr)
            return 2
    gf, ge = fast["gradients"], exact["gradients"]
    r = len(ge)
    deviations = []
    for a, b in zip(gf, ge):
        nb = norm(b)
        deviations.append(norm([x - y for x, y in zip(a, b)]) / nb if nb > 0 else float("inf"))
    mean = [sum(col) / r for col in zip(*ge)]
    spread = math.sqrt(sum(norm([x - m for x, m in zip(g, mean)]) ** 2 for g in ge) / r)
    rel_se = spread / norm(mean)
    deviation = sum(deviations) / r
    ratio = deviation / rel_se if rel_se > 0 else float("inf")
    result = {
        "method": exact["method"], "episode": exact["episode"], "particles": exact["particles"],
        "horizon": exact["horizon"], "replicates": r, "snapshot": exact["snapshot"],
        "fast_blas": fast.get("blas"), "exact_blas": exact.get("blas"),
        "deviation": deviation, "max_deviation": max(deviations), "rel_se": rel_se,
        "ratio": ratio, "threshold": args.threshold, "pass": ratio < args.threshold,
    }
    print(json.dumps(result))
    return 0 if result["pass"] else 1


if __name__ == "__main__":
    sys.exit(main())
