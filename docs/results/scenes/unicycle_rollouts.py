#!/usr/bin/env python3
"""Per-rollout summary of a unicycle `totalgrad evaluate --states` file.

    python3 docs/results/scenes/unicycle_rollouts.py STATES.csv > ROLLOUTS.csv

For each rollout: its cost (the sum of the steps' costs; the first row is
the initial state, which has none), the step at which
it fell (the first step whose states are empty: a real unicycle episode ends
when roll or pitch passes pi/2, and every later step costs 1; empty if it
stayed up), and, for a rollout that stayed up, its distance from the origin
in the ground plane at the last step (xc, yc). A summary line goes to stderr.
"""
import csv
import math
import statistics
import sys
from collections import defaultdict


def main():
    by_rollout = defaultdict(list)
    with open(sys.argv[1]) as f:
        for row in csv.DictReader(f):
            by_rollout[int(row["rollout"])].append(row)
    out = csv.writer(sys.stdout, lineterminator="\n")
    out.writerow(["rollout", "cost", "fall_step", "ground_distance_at_end"])
    falls, distances = [], []
    for rollout in sorted(by_rollout):
        rows = by_rollout[rollout]
        cost = sum(float(r["cost"]) for r in rows if r["cost"] != "")  # step 0: no cost yet
        fall = next((int(r["step"]) for r in rows if r["dtheta"] == ""), None)
        distance = None
        if fall is None:
            distance = math.hypot(float(rows[-1]["xc"]), float(rows[-1]["yc"]))
            distances.append(distance)
        else:
            falls.append(fall)
        out.writerow([rollout, f"{cost:.6g}", "" if fall is None else fall,
                      "" if distance is None else f"{distance:.6g}"])
    summary = f"{len(falls)} of {len(by_rollout)} fell"
    if len(falls) >= 2:
        q = statistics.quantiles(falls, n=4)
        summary += f" (fall step quartiles {q[0]:g}, {q[1]:g}, {q[2]:g})"
    if distances:
        summary += (f"; {len(distances)} stayed up, ground distance at the end median "
                    f"{statistics.median(distances):.3g}, min {min(distances):.3g}")
    print(summary, file=sys.stderr)


if __name__ == "__main__":
    main()
