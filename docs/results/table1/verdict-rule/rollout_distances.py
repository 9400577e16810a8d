#!/usr/bin/env python3
"""The numbers behind the rollout verdict's rule (docs/results/table1.md, "The
rollout verdict"): for each rollouts CSV written by `totalgrad evaluate
--states` on the cart-pole, the pole tip's distance from the upright tip above
the target, d_t = sqrt((s + l sin beta)^2 + l^2 (cos beta + 1)^2), l = 0.5 m,
and per rollout its largest d over the last T seconds (T = 0.5, 1, 1.5 s):
a rollout is held under the rule (D, T) when that maximum is at most D.

usage: rollout_distances.py LABEL=FILE.csv[.gz] ...   (one table per file, then the
largest distance over the last second pooled over every file, as a histogram)
"""
import csv
import gzip
import math
import sys

L = 0.5
HOLDS = (5, 10, 15)  # steps of 0.1 s


def quantiles(values):
    v = sorted(values)
    def q(p):
        x = p * (len(v) - 1)
        i = int(math.floor(x))
        j = min(i + 1, len(v) - 1)
        return v[i] + (v[j] - v[i]) * (x - i)
    return [q(p) for p in (0.0, 0.05, 0.25, 0.5, 0.75, 0.95, 1.0)]


def main(args):
    pooled = []
    for arg in args:
        label, path = arg.split("=", 1)
        rollouts = {}
        opener = gzip.open if path.endswith(".gz") else open
        with opener(path, "rt") as f:
            for row in csv.DictReader(f):
                r, t = int(row["rollout"]), int(row["step"])
                if t == 0:
                    continue
                s, beta = float(row["s"]), float(row["beta"])
                d = math.hypot(s + L * math.sin(beta), L * (math.cos(beta) + 1.0))
                rollouts.setdefault(r, []).append((t, d, float(row["cost"])))
        print(f"## {label}: {len(rollouts)} rollouts ({path})")
        costs = [sum(c for _, _, c in steps) for steps in rollouts.values()]
        print("episode cost min/p5/q1/median/q3/p95/max: " +
              " ".join(f"{x:.2f}" for x in quantiles(costs)))
        for hold in HOLDS:
            worst = [max(d for t, d, _ in steps if t > len(steps) - hold)
                     for steps in rollouts.values()]
            print(f"max tip distance over the last {hold / 10:.1f} s, min/p5/q1/median/q3/p95/max: " +
                  " ".join(f"{x:.3f}" for x in quantiles(worst)))
            if hold == 10:
                pooled.extend(worst)
            for limit in (0.1, 0.2, 0.25, 0.3, 0.4, 0.5):
                held = sum(1 for w in worst if w <= limit)
                print(f"  held within {limit:.2f} m: {held}/{len(worst)}")
        print()
    edges = [0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, math.inf]
    print(f"## pooled: largest tip distance over the last 1.0 s, {len(pooled)} rollouts")
    for low, high in zip(edges, edges[1:]):
        print(f"[{low}, {high}) m: {sum(1 for w in pooled if low <= w < high)}")


if __name__ == "__main__":
    main(sys.argv[1:])
