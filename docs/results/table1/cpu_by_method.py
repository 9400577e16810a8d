#!/usr/bin/python3
"""CPU time of the completed Table-1 trials per method, against the cost model.

    cpu_by_method.py TOTALGRAD_CLI ARCHIVE...

For each completed trial of the archives: its measured CPU seconds (the sum of
`cpu_seconds` over the completed attempt's episodes; a resumed attempt carries
the restored episodes' own times, so this is the trial's CPU, not the last
attempt's) and the cost model's estimate for its options (`totalgrad bench
estimate --KEY VALUE ...`, docs/results/cost-model.md). Prints per method the
trials, measured and estimated CPU minutes (median) and the ratio of the
totals, then the builds the trials ran on.
"""
import collections
import json
import statistics
import subprocess
import sys


def estimate_seconds(cli, options):
    # Version 1 archives keep a job's options as an object, later ones as
    # [key, text] pairs.
    pairs = options.items() if isinstance(options, dict) else options
    flags = []
    for key, value in pairs:
        flags += ["--" + key.replace("_", "-"), value]
    out = subprocess.run([cli, "bench", "estimate"] + flags, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out)["total_cpu_seconds"]


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    cli = sys.argv[1]
    measured = collections.defaultdict(list)
    estimated = collections.defaultdict(list)
    builds = collections.Counter()
    unmeasured = collections.Counter()
    for path in sys.argv[2:]:
        archive = json.load(open(path))
        for job in archive["jobs"]:
            if job["state"] != "completed":
                continue
            attempt = next(a for a in job["attempt_log"]
                           if a["attempt"] == job["completed_attempt"])
            builds[attempt["worker_build"]] += 1
            times = [e.get("cpu_seconds") for e in attempt["episodes"]]
            if any(t is None for t in times):
                unmeasured[job["method"]] += 1  # a build that did not record CPU time
                continue
            cpu = sum(times)
            measured[job["method"]].append(cpu)
            estimated[job["method"]].append(estimate_seconds(cli, job["options"]))
    print("method  trials  measured min (median)  estimated min (median)  measured/estimated (totals)")
    for method in measured:
        m, e = measured[method], estimated[method]
        print(f"{method:7} {len(m):6d}  {statistics.median(m) / 60:21.2f}  "
              f"{statistics.median(e) / 60:22.2f}  {sum(m) / sum(e):27.2f}")
    all_m = sum(sum(v) for v in measured.values())
    all_e = sum(sum(v) for v in estimated.values())
    print(f"all     {sum(len(v) for v in measured.values()):6d}  total {all_m / 3600:.2f} CPU h "
          f"measured, {all_e / 3600:.2f} estimated, ratio {all_m / all_e:.2f}")
    for method, count in unmeasured.items():
        print(f"{method}: {count} trials without CPU times (left out)")
    print("builds of the completed attempts:")
    for build, count in builds.most_common():
        print(f"  {count:4d}  {build}")


if __name__ == "__main__":
    main()
