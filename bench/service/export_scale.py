#!/usr/bin/env python3
"""Issue 28, items 1 and 3, by hand: S sweeps of N completed jobs each
(default one of 100,000, the per-sweep maximum; --sweeps 10 puts 1,000,000
jobs in the store), then, with all of them stored, one sweep listed,
exported (CSV and archive, through the coordinator and through --db),
deleted with its archive and imported back. For each step: its wall time,
the size written, the coordinator's peak RSS during the step (VmHWM, reset
before it through /proc/PID/clear_refs) and its RSS 10 s after the step
(the bound of item 3: under 200 MB). Not a CI test
(tests/service/scale_export_test.cc is, at 4,000 jobs).

    python3 bench/service/export_scale.py --build build --jobs 100000 --sweeps 10 \
        --port 7350 --json-out scale.jsonl

The jobs are made completed without running trials: the script submits the
sweeps, lists the first one's jobs (`job list -f json`), writes for each
sweep an archive in which each job completed attempt 1 with every expected
episode (the sweeps differ only in name, so one list serves all), and
imports it. Loopback only; everything lives in a temporary directory that is
removed at the end (--keep keeps it).
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--build", default="build")
    parser.add_argument("--jobs", type=int, default=100000, help="jobs per sweep")
    parser.add_argument("--sweeps", type=int, default=1)
    parser.add_argument("--port", type=int, default=7350)
    parser.add_argument("--settle-seconds", type=float, default=10)
    parser.add_argument("--json-out", help="append one JSON line per step to this file")
    parser.add_argument("--keep", action="store_true")
    args = parser.parse_args()
    build = os.path.abspath(args.build)
    work = tempfile.mkdtemp(prefix="export-scale-")
    db = os.path.join(work, "scale.db")
    coordinator = subprocess.Popen(
        [f"{build}/server/totalgrad-coordinator", "--db", db, "--init", "--insecure",
         "--listen", f"127.0.0.1:{args.port}"],
        stdout=subprocess.DEVNULL, stderr=open(os.path.join(work, "coordinator.log"), "w"))
    remote = ["--coordinator", f"127.0.0.1:{args.port}", "--insecure"]
    local = ["--db", db]
    names = [f"scale-{k}" for k in range(args.sweeps)]

    def cli(*argv, flags=remote, stdout=None):
        started = time.monotonic()
        done = subprocess.run([f"{build}/client/totalgrad", *argv, *flags, "--timeout", "1800"],
                              stdout=stdout or subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        seconds = time.monotonic() - started
        if done.returncode != 0:
            sys.exit(f"totalgrad {' '.join(argv)}: exit {done.returncode}: {done.stderr}")
        return done.stdout, seconds

    def status_mb(field):
        with open(f"/proc/{coordinator.pid}/status") as status:
            for line in status:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) / 1024
        return float("nan")

    def reset_peak():
        # Writing 5 resets the process's peak RSS (VmHWM) to its current RSS.
        with open(f"/proc/{coordinator.pid}/clear_refs", "w") as clear:
            clear.write("5")

    def report(step, seconds, path=None, settle=True):
        peak = status_mb("VmHWM")
        if settle:
            time.sleep(args.settle_seconds)
        settled = status_mb("VmRSS")
        size = os.path.getsize(path) if path else None
        size_text = f", {size / 2**20:.1f} MiB" if path else ""
        when = f"{args.settle_seconds:.0f} s after" if settle else "at its end"
        print(f"{step}: {seconds:.1f} s{size_text}; coordinator RSS peak {peak:.0f} MB, "
              f"{settled:.0f} MB {when}", flush=True)
        if args.json_out:
            with open(args.json_out, "a") as out:
                out.write(json.dumps({
                    "step": step, "seconds": round(seconds, 1), "bytes_written": size,
                    "jobs_in_store": jobs_in_store, "peak_rss_mb": round(peak, 1),
                    "rss_mb_after_settle": round(settled, 1),
                    "settle_seconds": args.settle_seconds if settle else 0,
                    "database_bytes": os.path.getsize(db)}) + "\n")
        reset_peak()

    jobs_in_store = 0
    try:
        time.sleep(1)
        reset_peak()
        for name in names:
            sweep_file = os.path.join(work, f"{name}.toml")
            with open(sweep_file, "w") as f:
                f.write(f'name = "{name}"\n[grid]\nmethod = ["RP"]\n'
                        f'seed = {{ first = 1, count = {args.jobs} }}\n'
                        '[protocol]\nepisodes = 1\npolicy_steps = 3\nparticles = 8\n'
                        'eval_rollouts = 2\nhorizon = 10\n')
            _, seconds = cli("sweep", "submit", sweep_file)
            jobs_in_store += args.jobs
            report(f"submit {name} ({args.jobs} jobs)", seconds, settle=name == names[-1])
        listed, seconds = cli("job", "list", "--sweep", names[0], "-f", "json")
        report(f"job list -f json ({names[0]})", seconds)
        # The archives' jobs, written once: every sweep has the same jobs.
        body = os.path.join(work, "jobs.part")
        with open(body, "w") as f:
            for i, job in enumerate(json.loads(listed)):
                job.update(state="completed", success=True, final_eval_cost=1.5,
                           completed_attempt=1)
                job["attempt_log"] = [{
                    "attempt": 1, "state": "completed", "worker_id": "w", "worker_host": "h",
                    "worker_build": "export_scale.py", "started_unix_ms": 1000,
                    "ended_unix_ms": 2000, "error": "", "origin": "",
                    "episodes": [{"episode": k, "real_cost": k + 0.25, "eval_cost_mean": k + 0.5,
                                  "eval_cost_std": 0.25, "predicted_cost": k,
                                  "optimisation_seconds": 0.01, "reported_unix_ms": 1500 + k,
                                  "details": {"n": 1}}
                                 for k in range(job["episodes_expected"])],
                    "study_cells": [], "study_references": []}]
                f.write(("," if i else "") + json.dumps(job) + "\n")
        del listed
        for name in names:
            sweep = json.loads(cli("sweep", "status", name, "-f", "json")[0])
            if isinstance(sweep, list):
                sweep = sweep[0]
            archive = os.path.join(work, "completed.json")
            with open(archive, "w") as f, open(body) as jobs:
                f.write(json.dumps({"format": "totalgrad-sweep-archive", "version": 4,
                                    "exported_by": "export_scale.py", "exported_unix_ms": 0,
                                    "sweep": sweep})[:-1] + ', "jobs": [\n')
                shutil.copyfileobj(jobs, f)
                f.write("]}\n")
            _, seconds = cli("results", "import", archive)
            report(f"results import {name} (completes every job)", seconds, archive,
                   settle=name == names[-1])
        os.remove(body)
        last = names[-1]
        _, seconds = cli("job", "list", "--sweep", last, "-f", "json", stdout=subprocess.DEVNULL)
        report(f"job list -f json ({last})", seconds)
        for flags, where in ((remote, "coordinator"), (local, "--db")):
            rows = os.path.join(work, f"rows-{where.strip('-')}.csv")
            _, seconds = cli("results", "export", last, "-o", rows, flags=flags)
            report(f"results export -f csv {last} ({where})", seconds, rows)
            exported = os.path.join(work, f"archive-{where.strip('-')}.json")
            _, seconds = cli("results", "export", last, "-f", "json", "-o", exported,
                             flags=flags)
            report(f"results export -f json {last} ({where})", seconds, exported)
            os.remove(exported)
            _, seconds = cli("results", "table", last, flags=flags)
            report(f"results table {last} ({where})", seconds)
        deleted = os.path.join(work, "deleted.json")
        out, seconds = cli("sweep", "delete", last, "--archive", deleted)
        jobs_in_store -= args.jobs
        report("sweep delete (" + out.splitlines()[0] + ")", seconds, deleted)
        out, seconds = cli("results", "import", deleted)
        jobs_in_store += args.jobs
        report("results import of the delete's archive (" + out.strip() + ")", seconds)
    finally:
        coordinator.terminate()
        coordinator.wait()
        if not args.keep:
            shutil.rmtree(work)


if __name__ == "__main__":
    main()
