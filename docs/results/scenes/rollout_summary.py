#!/usr/bin/python3
"""Per-rollout summary of `totalgrad evaluate --states` output, to judge what a
policy does rather than only what it costs.

usage: rollout_summary.py STATES.csv ANGLE_COLUMN [ANGLE_COLUMN ...] [--tolerance RAD] [--last STEPS]

For each rollout: its cost (sum of the per-step costs), whether every named
angle is within the tolerance of upright (0 mod 2 pi) over the last STEPS
states ("up at the end"), and the closest approach to upright (the smallest,
over time, of the largest wrapped angle), the first step whose cost falls
below 0.1 ("first_low_cost_step", empty if none) and the cost accrued before it
("cost_before_low"): what the rollout would cost had it held the state from
that step on at no cost, the floor for a swing-up at that moment. Prints CSV
on stdout and a one-line summary on stderr.
"""
import argparse
import sys

import numpy as np
import pandas as pd


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("states")
    parser.add_argument("angles", nargs="+")
    parser.add_argument("--tolerance", type=float, default=0.3)
    parser.add_argument("--last", type=int, default=10)
    args = parser.parse_args()
    d = pd.read_csv(args.states)
    missing = [a for a in args.angles if a not in d.columns]
    if missing:
        sys.exit(f"{args.states}: no column {missing}; columns are {list(d.columns)}")
    wrapped = np.abs((d[args.angles].to_numpy() + np.pi) % (2 * np.pi) - np.pi)
    d["worst_angle"] = wrapped.max(axis=1)
    horizon = d["step"].max()
    rows = []
    for rollout, x in d.groupby("rollout"):
        end = x[x["step"] > horizon - args.last]
        # Step 0 is the start state and has no cost (an empty field).
        costs = x[x["step"] > 0]
        low = costs[costs["cost"] < 0.1]
        first_low = int(low["step"].iloc[0]) if len(low) else None
        before = costs[costs["step"] < first_low]["cost"].sum() if first_low is not None else None
        rows.append({"rollout": rollout, "cost": x["cost"].sum(),
                     "up_at_end": int((end["worst_angle"] < args.tolerance).all()),
                     "closest_to_upright": x["worst_angle"].min(),
                     "first_low_cost_step": first_low, "cost_before_low": before})
    out = pd.DataFrame(rows)
    out["first_low_cost_step"] = out["first_low_cost_step"].astype("Int64")
    out.to_csv(sys.stdout, index=False, float_format="%.6g")
    print(f"{args.states}: {len(out)} rollouts, {out['up_at_end'].sum()} up at the end "
          f"(all of {args.angles} within {args.tolerance} rad over the last {args.last} steps); "
          f"cost median {out['cost'].median():.2f}, min {out['cost'].min():.2f}, "
          f"max {out['cost'].max():.2f}", file=sys.stderr)


if __name__ == "__main__":
    main()
