#!/usr/bin/python3
"""Does this build repeat an archived trial bit for bit?

When the build that ran a sweep is gone (a new machine, a new session), the
archive is the reference: this re-runs the first EPISODES episodes of an
archived, completed trial with the given `totalgrad` CLI and the job's stored
options, and compares every number the archive kept for those episodes (the
episode record and its details, timings aside) with what the CLI prints.
A trial's episodes do not depend on how many follow them, so a prefix is the
same computation as the archived trial's first episodes (but the verdict,
which runs after the final episode only).

  bench/same_bits_archive.py CLI ARCHIVE METHOD SEED [--episodes N] [--out F]

Prints one line per episode and "same bits" or the first differing key;
exits 1 on a difference, 2 on bad input.
"""
import argparse
import json
import subprocess
import sys

# Timings differ from run to run; the archive's own bookkeeping is not a result.
SKIPPED_KEYS = {"timing", "cpu_seconds", "optimisation_seconds", "seconds",
                "reported_unix_ms", "wall_seconds"}


def flatten(prefix, value, out):
    if isinstance(value, str) and value[:1] in "[{":
        try:
            value = json.loads(value)  # details and lr_share are JSON text in the archive
        except ValueError:
            pass
    if isinstance(value, dict):
        for key, item in value.items():
            if key == "details":  # the archive nests what the CLI prints at the top
                flatten(prefix, item, out)
            elif key not in SKIPPED_KEYS:
                flatten(f"{prefix}.{key}" if prefix else key, item, out)
    else:
        out[prefix] = value


def archived_job(archive, method, seed):
    for job in archive["jobs"]:
        if job["method"] == method and str(job["seed"]) == str(seed) and job["state"] == "completed":
            attempt = next(a for a in job["attempt_log"] if a["attempt"] == job["completed_attempt"])
            return job, attempt
    sys.exit(f"no completed {method} seed {seed} in the archive")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cli")
    parser.add_argument("archive")
    parser.add_argument("method")
    parser.add_argument("seed")
    parser.add_argument("--episodes", type=int, default=3, help="learned episodes to re-run")
    parser.add_argument("--out", help="also write the CLI's JSON lines here")
    args = parser.parse_args()
    with open(args.archive) as f:
        archive = json.load(f)
    job, attempt = archived_job(archive, args.method, args.seed)
    command = [args.cli, "trial", "--json"]
    for key, text in job["options"]:
        if key == "episodes":
            text = str(args.episodes)
        command += ["--set", f"{key}={text}"]
    run = subprocess.run(command, capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"the trial failed ({run.returncode}): {run.stderr.strip()}")
    if args.out:
        with open(args.out, "w") as f:
            f.write(run.stdout)
    fresh = [json.loads(line) for line in run.stdout.splitlines() if '"episode"' in line]
    stored = {e["episode"]: e for e in attempt["episodes"]}
    build = attempt.get("worker_build", "?")
    compared = 0
    for episode in fresh:
        number = episode["episode"]
        if number not in stored:
            print(f"episode {number}: not in the archive"); return 1
        new, old = {}, {}
        flatten("", episode, new)
        flatten("", stored[number], old)
        common = set(new) & set(old)
        if number == fresh[-1]["episode"]:
            # The prefix's last episode is its final one, where the trial runs the
            # verdict rollouts; the archived trial ran them only after its own.
            common.discard("held_fraction")
        common = sorted(common)
        for key in common:
            if json.dumps(new[key]) != json.dumps(old[key]):
                print(f"{args.method} seed {args.seed} episode {number}: {key} differs: "
                      f"{old[key]} (archive, {build}) vs {new[key]} (this build)")
                return 1
        compared += len(common)
        print(f"episode {number}: same bits ({len(common)} values)")
    if not fresh:
        print("the CLI printed no episode"); return 1
    print(f"{args.method} seed {args.seed}: same bits as the archive's attempt "
          f"{attempt['attempt']} ({build}): {len(fresh)} episodes, {compared} values")
    return 0


if __name__ == "__main__":
    sys.exit(main())
