#!/usr/bin/env python3
"""The final checks of netns_multihost_test.sh, on the stopped coordinator's
SQLite file and the CLI's exports:

  * every job completed; its result rows (`results export`) are episodes
    0..N-1 of its completed attempt, each exactly once;
  * each row is bit-equal to the same trial run in-process (`totalgrad trial`
    with the job's stored options): trials are deterministic;
  * the cut job: attempt 1 (the cut worker) ended lease_lost, the completed
    attempt belongs to the other worker, one lost lease counted;
  * no episode of a lost attempt was stored after the attempt ended (the cut
    worker's late reports were refused).
"""
import argparse
import json
import math
import sqlite3
import subprocess
import sys

FIELDS = ("real_cost", "eval_cost_mean", "eval_cost_std", "predicted_cost")
problems = []


def problem(message):
    problems.append(message)
    print("FAIL: " + message)


def read_jsonl(path):
    with open(path, encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]


def same(a, b):
    if a is None or b is None:
        return a is None and b is None
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return float(a) == float(b)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--db", required=True)
    parser.add_argument("--rows", required=True)
    parser.add_argument("--all-rows", required=True)
    parser.add_argument("--cli", required=True)
    parser.add_argument("--cut-job", type=int, required=True)
    parser.add_argument("--cut-worker", required=True)
    parser.add_argument("--other-worker", required=True)
    args = parser.parse_args()

    db = sqlite3.connect(f"file:{args.db}?mode=ro", uri=True)
    jobs = db.execute("SELECT j.id, j.seed, j.state, j.completed_attempt, j.episodes_expected, "
                      "l.options_json, j.lost_leases FROM jobs j "
                      "JOIN job_option_lists l ON l.job_id = j.id ORDER BY j.id").fetchall()
    rows = read_jsonl(args.rows)
    all_rows = read_jsonl(args.all_rows)
    print(f"{len(jobs)} jobs, {len(rows)} result rows, {len(all_rows)} rows of all attempts")

    by_job = {}
    for row in rows:
        key = (row["job_id"], row["episode"])
        if key in by_job:
            problem(f"row {key} exported twice")
        by_job[key] = row

    expected_keys = set()
    for job_id, seed, state, completed_attempt, expected, options_json, lost in jobs:
        if state != "completed":
            problem(f"job {job_id} is {state}, not completed")
            continue
        expected_keys |= {(job_id, e) for e in range(expected)}
        stored = db.execute("SELECT episode FROM episodes WHERE job_id = ? AND attempt = ? "
                            "ORDER BY episode", (job_id, completed_attempt)).fetchall()
        if [e for (e,) in stored] != list(range(expected)):
            problem(f"job {job_id}: stored episodes {stored} of attempt {completed_attempt}")
        for e in range(expected):
            row = by_job.get((job_id, e))
            if row and row["attempt"] != completed_attempt:
                problem(f"job {job_id} episode {e}: exported from attempt {row['attempt']}, "
                        f"not the completed attempt {completed_attempt}")

        # The reference: the same trial in-process.
        options = json.loads(options_json)
        command = [args.cli, "trial", "--json"]
        for key, value in options:
            command += ["--set", f"{key}={value}"]
        result = subprocess.run(command, capture_output=True, text=True, timeout=300)
        if result.returncode != 0:
            problem(f"job {job_id}: reference trial failed: {result.stderr}")
            continue
        reference = [json.loads(l) for l in result.stdout.splitlines() if '"episode"' in l]
        if len(reference) != expected:
            problem(f"job {job_id}: the reference trial has {len(reference)} episodes, "
                    f"the job expects {expected}")
        mismatches = 0
        for ref in reference:
            row = by_job.get((job_id, ref["episode"]))
            if row is None:
                continue
            for field in FIELDS:
                if ref.get(field) is None:
                    continue
                if not same(ref[field], row.get(field)):
                    mismatches += 1
                    problem(f"job {job_id} episode {ref['episode']} {field}: stored "
                            f"{row.get(field)!r}, in-process {ref[field]!r}")
        if mismatches == 0:
            print(f"job {job_id} (seed {seed}): {expected} episodes bit-equal to the in-process run")

    exported_keys = set(by_job)
    if exported_keys != expected_keys:
        problem(f"exported rows differ from the expected set: missing "
                f"{sorted(expected_keys - exported_keys)}, extra {sorted(exported_keys - expected_keys)}")
    else:
        print(f"result rows are exactly the expected set ({len(expected_keys)} rows)")

    # The cut job's attempts.
    attempts = db.execute("SELECT attempt, worker_id, state, ended_ms FROM attempts WHERE job_id = ? "
                          "ORDER BY attempt", (args.cut_job,)).fetchall()
    print(f"job {args.cut_job} attempts: {attempts}")
    if not attempts or attempts[0][1] != args.cut_worker or attempts[0][2] != "lease_lost":
        problem(f"job {args.cut_job}: attempt 1 should be {args.cut_worker}'s, lease_lost")
    completed = [a for a in attempts if a[2] == "completed"]
    if len(completed) != 1 or completed[0][1] != args.other_worker:
        problem(f"job {args.cut_job}: should be completed once, by {args.other_worker}")
    lost = [j for j in jobs if j[0] == args.cut_job][0][6]
    if lost != 1:
        problem(f"job {args.cut_job}: {lost} lost leases counted (expected 1)")

    # Late writes: nothing stored for an ended attempt after it ended.
    late = db.execute("SELECT e.job_id, e.attempt, e.episode, e.reported_ms, a.ended_ms "
                      "FROM episodes e JOIN attempts a ON a.job_id = e.job_id AND a.attempt = e.attempt "
                      "WHERE a.state <> 'completed' AND e.reported_ms > a.ended_ms").fetchall()
    if late:
        problem(f"episodes stored after their attempt ended: {late}")
    lost_rows = [r for r in all_rows if r["job_id"] == args.cut_job and r["attempt"] == 1]
    print(f"{len(lost_rows)} episode(s) of the lost attempt were stored before the cut and "
          f"none after it ended; they are not results (final_attempt = "
          f"{sorted({r['final_attempt'] for r in lost_rows})})")
    if any(r["final_attempt"] for r in lost_rows):
        problem("rows of the lost attempt are marked final")
    if not lost_rows:
        problem("the lost attempt stored no episode: the cable was not pulled mid-trial")

    print("verify: " + ("OK" if not problems else f"{len(problems)} problem(s)"))
    sys.exit(1 if problems else 0)


if __name__ == "__main__":
    main()
