#!/usr/bin/python3
"""The recipe of docs/results_schema.md, run as a user would: one sweep on
this machine (`totalgrad run`), then one pandas.read_sql of the sweep's view
gives one row per episode with every swept key as a typed column.

    pandas_view_test.py TOTALGRAD_BIN WORK_DIR

Debian's python3-pandas (/usr/bin/python3; a `python3` earlier on PATH may
lack it). Exit 0 on success, 1 with the failed check on stderr.
"""
import io
import os
import shutil
import sqlite3
import subprocess
import sys

import pandas

SWEEP = """name = "pandas"
[grid]
method = ["RP", "TP"]
noise_k = [0.01, 1.0]
seed = [3, 4]
[protocol]
episodes = 2
policy_steps = 3
particles = 8
eval_rollouts = 2
horizon = 10
"""


def check(condition, message):
    if not condition:
        print("FAIL: " + message, file=sys.stderr)
        sys.exit(1)


def main():
    binary, work = sys.argv[1], sys.argv[2]
    shutil.rmtree(work, ignore_errors=True)  # a fresh database every run
    os.makedirs(work)
    sweep_file = os.path.join(work, "pandas.toml")
    with open(sweep_file, "w") as f:
        f.write(SWEEP)
    run = subprocess.run([binary, "run", sweep_file, "--dir", work, "--workers", "2", "--no-plot"],
                         capture_output=True, text=True, timeout=300)
    check(run.returncode == 0, "totalgrad run failed:\n" + run.stdout + run.stderr)
    db = os.path.join(work, "pandas.db")
    # The whole recipe: one query of the sweep's view.
    frame = pandas.read_sql('SELECT * FROM "episodes/pandas"', sqlite3.connect(db))
    check(len(frame) == 8 * 3, f"expected 24 episode rows (8 jobs x 3 episodes), got {len(frame)}")
    for column in ("method", "seed", "noise_k", "episode", "eval_cost_mean", "cpu_seconds",
                   "optimisation_seconds", "final_attempt", "worker_build"):
        check(column in frame.columns, f"column {column} missing: {list(frame.columns)}")
    check(str(frame["seed"].dtype).startswith("int"), f"seed is {frame['seed'].dtype}, not an integer")
    check(str(frame["noise_k"].dtype).startswith("float"), f"noise_k is {frame['noise_k'].dtype}")
    check(sorted(frame["noise_k"].unique().tolist()) == [0.01, 1.0], "noise_k values")
    check(sorted(frame["seed"].unique().tolist()) == [3, 4], "seed values")
    check((frame["cpu_seconds"] > 0).all(), "every episode has its CPU seconds")
    # What a researcher does next: the final evaluation cost per method and noise level.
    # The recipe's filter: the counting attempt of finished trials only.
    check("job_state" in frame.columns, "column job_state missing")
    done = frame[(frame["final_attempt"] == 1) & (frame["job_state"] == "completed")]
    check(len(done) == 8 * 3, f"24 rows of completed trials expected, got {len(done)}")
    last = done[done["episode"] == 2]
    table = last.groupby(["method", "noise_k"])["eval_cost_mean"].median()
    check(len(table) == 4, f"4 (method, noise_k) groups expected, got {len(table)}")
    print(table.to_string())
    # One column set (issue 29): the view's columns are the CSV export's, in
    # its order, between the sweep's name and worker_build (version 9 also
    # kept wall_seconds, optimisation_seconds' name until version 8; version
    # 10 drops it); the protocol's options are typed columns too.
    export = subprocess.run([binary, "results", "export", "pandas", "--db", db, "-f", "csv"],
                            capture_output=True, text=True, timeout=120)
    check(export.returncode == 0, "results export failed: " + export.stderr)
    csv_columns = export.stdout.splitlines()[0].split(",")
    view_columns = list(frame.columns)
    check(view_columns == ["sweep"] + csv_columns + ["worker_build"],
          f"view columns {view_columns} are not the CSV's {csv_columns}")
    check((frame["particles"] == 8).all() and str(frame["particles"].dtype).startswith("int"),
          f"particles is a typed protocol column: {frame['particles'].dtype}")
    check((frame["scene"] == "cartpole-swingup").all(), "scene is a protocol column")
    check((frame["threshold"] == 15).all() and (frame["horizon"] == 10).all(),
          "threshold and horizon as resolved for the scene")
    check("wall_seconds" not in frame.columns, "wall_seconds was kept for schema 9 only")
    # round_trip: the CSV holds the shortest text of each double; pandas' fast
    # parser can miss it by an ulp.
    csv_rows = pandas.read_csv(io.StringIO(export.stdout), float_precision="round_trip")
    merged = csv_rows.merge(frame, on=["job_id", "attempt", "episode"], suffixes=("_csv", "_view"))
    check(len(merged) == len(frame), "every view row is an exported row")
    for column in ("eval_cost_mean", "optimisation_seconds", "cpu_seconds", "final_eval_cost", "noise_k"):
        same = (merged[column + "_csv"] - merged[column + "_view"]).abs().max()
        check(same == 0, f"{column} differs between the CSV and the view by {same}")
    check((merged["final_attempt_csv"].astype(int) == merged["final_attempt_view"]).all(),
          "final_attempt means the same in both")
    return 0


if __name__ == "__main__":
    sys.exit(main())
