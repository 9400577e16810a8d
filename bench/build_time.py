#!/usr/bin/env python3
"""How long `make demo` (or `make test`) takes from a fresh clone, and where
the compile time goes, as JSON.

    bench/build_time.py [--repo DIR] [--make-target demo|binaries|test] [--out FILE]

Clones DIR (default: this repository, its HEAD commit) into a temporary
directory, runs `make TARGET` there under /usr/bin/time and reads the Ninja
log of the new build directory: the seconds of every build step, summed per
CMake target (each step is one compiler or linker process, so the sum is
close to the CPU seconds it used). The install step is part of the time, but
on a machine that already has the packages it is only the check.

Run it with nothing else busy (stop the workers first; see the brief): the
figures are seconds of a 2-core machine, not instruction counts.
"""
import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time


def steps_by_target(ninja_log):
    """Sums the durations of the last run of every output, per CMake target."""
    latest = {}
    with open(ninja_log) as log:
        for line in log:
            if line.startswith("#"):
                continue
            fields = line.rstrip("\n").split("\t")
            if len(fields) < 4:
                continue
            start_ms, end_ms, output = int(fields[0]), int(fields[1]), fields[3]
            latest[output] = (start_ms, end_ms)
    by_target = {}
    for output, (start_ms, end_ms) in latest.items():
        match = re.search(r"CMakeFiles/([^/]+)\.dir/", output)
        if match:
            target = match.group(1)
        else:  # a link step names the binary or library it writes
            target = os.path.basename(output)
            target = re.sub(r"^lib(.*)\.a$", r"\1", target)
        entry = by_target.setdefault(target, {"target": target, "seconds": 0.0, "steps": 0})
        entry["seconds"] += (end_ms - start_ms) / 1000.0
        entry["steps"] += 1
    return sorted(by_target.values(), key=lambda e: -e["seconds"]), len(latest)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repo", default=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    parser.add_argument("--make-target", default="demo", choices=["demo", "binaries", "test"])
    parser.add_argument("--out", help="write the JSON here as well as to stdout")
    parser.add_argument("--keep", action="store_true", help="keep the clone (its path is printed)")
    args = parser.parse_args()

    commit = subprocess.run(["git", "-C", args.repo, "rev-parse", "HEAD"], check=True,
                            capture_output=True, text=True).stdout.strip()
    workdir = tempfile.mkdtemp(prefix="totalgrad-build-time-")
    clone = os.path.join(workdir, "totalgrad")
    subprocess.run(["git", "clone", "--quiet", args.repo, clone], check=True)
    subprocess.run(["git", "-C", clone, "checkout", "--quiet", commit], check=True)
    with open("/proc/loadavg") as f:
        load_before = f.read().split()[0]
    time_file = os.path.join(workdir, "time.txt")
    log_file = os.path.join(workdir, "make.log")
    started = time.time()
    with open(log_file, "w") as log:
        result = subprocess.run(["/usr/bin/time", "-f", "%e %U %S", "-o", time_file, "make",
                                 args.make_target], cwd=clone, stdout=log, stderr=subprocess.STDOUT)
    wall = time.time() - started
    with open(time_file) as f:
        elapsed, user, system = (float(x) for x in f.read().split()[-3:])
    ninja_log = os.path.join(clone, "build", ".ninja_log")
    targets, steps = steps_by_target(ninja_log) if os.path.exists(ninja_log) else ([], 0)
    report = {
        "benchmark": "build_time",
        "make_target": args.make_target,
        "commit": commit,
        "exit_code": result.returncode,
        "wall_seconds": round(elapsed if elapsed > 0 else wall, 1),
        "user_seconds": round(user, 1),
        "system_seconds": round(system, 1),
        "build_steps": steps,
        "step_seconds_total": round(sum(t["seconds"] for t in targets), 1),
        "by_target": [{"target": t["target"], "seconds": round(t["seconds"], 1),
                       "steps": t["steps"]} for t in targets],
        "cores": os.cpu_count(),
        "load_average_before": float(load_before),
    }
    text = json.dumps(report, indent=2)
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")
    if result.returncode != 0:
        with open(log_file) as f:
            sys.stderr.write(f.read()[-4000:])
    if args.keep:
        print(f"clone kept at {clone}", file=sys.stderr)
    else:
        shutil.rmtree(workdir, ignore_errors=True)
    return result.returncode


if __name__ == "__main__":
    sys.exit(main())
