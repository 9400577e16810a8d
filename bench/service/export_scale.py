#!/usr/bin/env python3
"""Issue 28, item 1, by hand: a sweep of N completed jobs (default 100,000,
the per-sweep maximum) listed, exported (CSV and archive, through the
coordinator and through --db), deleted with its archive and imported back,
with the wall time of each step, the sizes written and the coordinator's
peak RSS. Not a CI test (tests/service/scale_export_test.cc is, at 4,000).

    python3 bench/service/export_scale.py --build build --jobs 100000 --port 7350

The jobs are made completed without running trials: the script submits the
sweep, lists its jobs (`job list -f json`), writes an archive in which each
completed attempt 1 with every expected episode, and imports it. Loopback
only; everything lives in a temporary directory that is removed at the end
(--keep keeps it).
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
    parser.add_argument("--jobs", type=int, default=100000)
    parser.add_argument("--port", type=int, default=7350)
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

    def cli(*argv, flags=remote, stdout=None):
        started = time.monotonic()
        done = subprocess.run([f"{build}/client/totalgrad", *argv, *flags, "--timeout", "600"],
                              stdout=stdout or subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        seconds = time.monotonic() - started
        if done.returncode != 0:
            sys.exit(f"totalgrad {' '.join(argv)}: exit {done.returncode}: {done.stderr}")
        return done.stdout, seconds

    def peak_rss_mb():
        with open(f"/proc/{coordinator.pid}/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
        return float("nan")

    def report(step, seconds, path=None):
        size = f", {os.path.getsize(path) / 2**20:.1f} MiB" if path else ""
        print(f"{step}: {seconds:.1f} s{size}; coordinator peak RSS {peak_rss_mb():.0f} MB",
              flush=True)

    try:
        time.sleep(1)
        sweep_file = os.path.join(work, "scale.toml")
        with open(sweep_file, "w") as f:
            f.write(f'name = "scale"\n[grid]\nmethod = ["RP"]\n'
                    f'seed = {{ first = 1, count = {args.jobs} }}\n'
                    '[protocol]\nepisodes = 1\npolicy_steps = 3\nparticles = 8\n'
                    'eval_rollouts = 2\nhorizon = 10\n')
        _, seconds = cli("sweep", "submit", sweep_file)
        report(f"submit {args.jobs} jobs", seconds)
        listed, seconds = cli("job", "list", "--sweep", "scale", "-f", "json")
        report("job list -f json", seconds)
        jobs = json.loads(listed)
        sweep = json.loads(cli("sweep", "status", "scale", "-f", "json")[0])
        if isinstance(sweep, list):
            sweep = sweep[0]
        archive = os.path.join(work, "completed.json")
        with open(archive, "w") as f:
            f.write(json.dumps({"format": "totalgrad-sweep-archive", "version": 4,
                                "exported_by": "export_scale.py", "exported_unix_ms": 0,
                                "sweep": sweep})[:-1] + ', "jobs": [\n')
            for i, job in enumerate(jobs):
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
            f.write("]}\n")
        del jobs, listed
        _, seconds = cli("results", "import", archive)
        report("results import (completes every job)", seconds, archive)
        for flags, name in ((remote, "coordinator"), (local, "--db")):
            rows = os.path.join(work, f"rows-{name.strip('-')}.csv")
            _, seconds = cli("results", "export", "scale", "-o", rows, flags=flags)
            report(f"results export -f csv ({name})", seconds, rows)
            exported = os.path.join(work, f"archive-{name.strip('-')}.json")
            _, seconds = cli("results", "export", "scale", "-f", "json", "-o", exported,
                             flags=flags)
            report(f"results export -f json ({name})", seconds, exported)
            _, seconds = cli("results", "table", "scale", flags=flags)
            report(f"results table ({name})", seconds)
        deleted = os.path.join(work, "deleted.json")
        out, seconds = cli("sweep", "delete", "scale", "--archive", deleted)
        report("sweep delete (" + out.splitlines()[0] + ")", seconds, deleted)
        out, seconds = cli("results", "import", deleted)
        report("results import of the delete's archive (" + out.strip() + ")", seconds)
    finally:
        coordinator.terminate()
        coordinator.wait()
        if not args.keep:
            shutil.rmtree(work)


if __name__ == "__main__":
    main()
