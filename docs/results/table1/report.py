#!/usr/bin/python3
"""Issue 16's tables from sweep archives (`totalgrad results export SWEEP -f json`).

For every method of each archive: successes / n of the completed trials, the
95% Wilson interval, the paper's rate (Table 1 of the paper, where it has one)
and whether it lies inside our interval, the median final evaluation cost with
its quartiles, the CPU hours the trials took (the per-episode CPU seconds the
workers reported) against the cost model's estimate for the same options
(`totalgrad bench estimate`), and the builds that ran the trials.

Usage: report.py [--totalgrad BIN] [--rerun SWEEP=RERUN.json]... [--same-as REF.json]
                 ARCHIVE.json...
Prints Markdown on stdout. Reads nothing but the archives (and asks BIN for
the cost model, when given).

--rerun SWEEP=RERUN.json: the completed trials of the archive RERUN.json take
the place of SWEEP's trials with the same method and seed (a re-run with a
later build of trials whose build is known to be wrong); the table says which
trials were replaced. Only trials with the same options (seed aside) replace.

A sweep with task variants (options swept beside method and seed, such as
the follow-up's `normalisation`) gets one row per method and variant, and a
per-seed table of final costs side by side, variant against variant.

--same-as REFERENCE.json: the determinism check across sweeps: every
completed trial of the archives whose options (seed included) agree with
those of a completed trial in REFERENCE.json on every key both state is
compared episode by episode
(evaluation cost means); the report says which agree bit for bit, and which
builds ran the two (the same seed gives the same trial only on the same
build).
"""
import argparse
import json
import math
import statistics
import subprocess
import sys

# The paper's Table 1, swing-up: (cost, k) -> method -> success rate.
PAPER_RATES = {
    ("tip", "1"): {"PILCO": 0.73, "RP": 0.15, "GR": 0.68, "LR": 0.28, "TP": 0.48,
                   "GTP": 0.69, "GLR": 0.35},
    ("tip", "0.01"): {"PILCO": 0.92, "RP": 0.44, "GR": 0.47, "LR": 0.36, "TP": 0.54,
                      "GTP": 0.6, "GLR": 0.45, "GTP+sn": 0.8},
    ("angle", "1"): {"PILCO": 0.79, "RP": 0.74, "GR": 0.89, "LR": 0.96, "TP": 0.99,
                     "GTP": 0.9, "GLR": 0.93},
    ("angle", "0.01"): {"PILCO": 0.88, "RP": 0.69, "GR": 0.63, "LR": 0.57, "TP": 0.82,
                        "GTP": 0.65, "GLR": 0.42, "GTP+sn": 0.88},
}


def wilson_interval(successes, n, z=1.959963984540054):
    if n == 0:
        return (0.0, 1.0)
    p = successes / n
    denominator = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denominator
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denominator
    return (max(0.0, centre - half), min(1.0, centre + half))


def quartiles(values):
    if len(values) < 2:
        return (values[0], values[0], values[0]) if values else (math.nan,) * 3
    q1, q2, q3 = statistics.quantiles(values, n=4, method="inclusive")
    return (q1, q2, q3)


def paper_rate(options, method):
    if options.get("scene") != "cartpole-swingup":
        return None
    k = options.get("noise_k", "1")
    k = "0.01" if k in ("0.01", "0.01000000000000000021") else k
    return PAPER_RATES.get((options.get("cost"), k), {}).get(method)


def completed_attempt(job):
    for attempt in job.get("attempt_log", []):
        if attempt.get("attempt") == job.get("completed_attempt"):
            return attempt
    return None


def estimated_cpu_seconds(binary, options, cache):
    """The cost model's CPU seconds for one trial with these options."""
    if not binary:
        return None
    keys = tuple(sorted((k, v) for k, v in options.items() if k != "seed"))
    if keys not in cache:
        command = [binary, "bench", "estimate"]
        for key, value in keys:
            command += ["--set", f"{key}={value}"]
        result = subprocess.run(command, capture_output=True, text=True)
        if result.returncode != 0:
            print(f"bench estimate failed: {result.stderr.strip()}", file=sys.stderr)
            cache[keys] = None
        else:
            cache[keys] = json.loads(result.stdout)["total_cpu_seconds"]
    return cache[keys]


def job_options(job):
    """A job's options as a dict: archives of version 3 hold [key, text]
    pairs, earlier ones an object."""
    return dict(job["options"])


def options_without_seed(job):
    return {k: v for k, v in job_options(job).items() if k != "seed"}


def apply_reruns(sweep_name, jobs, reruns):
    """Replaces jobs by completed re-runs of the same (method, seed, options)."""
    replaced = []
    for rerun_path in reruns.get(sweep_name, []):
        rerun = json.load(open(rerun_path))
        for new in rerun["jobs"]:
            if new.get("kind") != "trial" or new.get("state") != "completed":
                continue
            for i, old in enumerate(jobs):
                if (old["method"], str(old["seed"])) == (new["method"], str(new["seed"])) and \
                        options_without_seed(old) == options_without_seed(new):
                    jobs[i] = new
                    replaced.append(f"{new['method']} s{new['seed']} "
                                    f"(from {rerun['sweep']['name']})")
    return replaced


def report(archive_path, binary, cache, reruns):
    archive = json.load(open(archive_path))
    sweep = archive["sweep"]
    jobs = [job for job in archive["jobs"] if job.get("kind") == "trial"]
    replaced = apply_reruns(sweep["name"], jobs, reruns)
    # Rows: (method, variant) in first-appearance order; the variant is the
    # sweep's task variant ("" in a sweep without one).
    rows = []
    for job in jobs:
        if (job["method"], job.get("variant", "")) not in rows:
            rows.append((job["method"], job.get("variant", "")))
    has_variants = any(variant for _, variant in rows)
    print(f"### {sweep['name']}: {sweep.get('description', '')}\n")
    completed = [job for job in jobs if job.get("state") == "completed"]
    print(f"{len(completed)} of {len(jobs)} trials completed "
          f"(archive exported by {archive['exported_by']}).\n")
    if replaced:
        print(f"Re-run trials in place of this sweep's own: {', '.join(replaced)}.\n")
    variant_header = "| variant " if has_variants else ""
    print(f"| method {variant_header}| successes / n | 95% Wilson | paper | paper inside? "
          "| final cost median [q1, q3] | CPU h (measured) | CPU min / trial: measured, model |")
    print("|---|---|---|---|---|---|---|---|" + ("---|" if has_variants else ""))
    builds = {}
    total_cpu = 0.0
    for method, variant in rows:
        def in_row(job):
            return job["method"] == method and job.get("variant", "") == variant
        done = [job for job in completed if in_row(job)]
        n = len(done)
        successes = sum(1 for job in done if job.get("success"))
        low, high = wilson_interval(successes, n)
        options = next(job_options(job) for job in jobs if in_row(job))
        rate = paper_rate(options, method)
        inside = "" if rate is None or n == 0 else ("yes" if low <= rate <= high else "**no**")
        costs = [job["final_eval_cost"] for job in done]
        q1, median, q3 = quartiles(costs) if costs else (math.nan,) * 3
        # CPU spent: every attempt of the completed trials (lost and released
        # attempts cost CPU too), as far as the workers reported it (builds
        # before per-episode CPU time report none). Per trial: only trials
        # whose counting attempt ran every episode itself and reported CPU
        # for each (a resumed attempt holds the CPU of its own episodes only).
        cpu = 0.0
        per_trial_cpu = []
        for job in done:
            for attempt in job["attempt_log"]:
                cpu += sum(episode.get("cpu_seconds") or 0.0 for episode in attempt["episodes"])
            attempt = completed_attempt(job)
            if attempt is None:
                continue
            builds.setdefault(attempt["worker_build"], []).append(trial_label(job))
            episodes = attempt["episodes"]
            if episodes and all(e.get("cpu_seconds") is not None for e in episodes) and \
                    len(episodes) == max(e["episode"] for e in episodes) + 1:
                per_trial_cpu.append(sum(e["cpu_seconds"] for e in episodes))
        total_cpu += cpu
        model = estimated_cpu_seconds(binary, options, cache)
        per_trial = (f"{statistics.mean(per_trial_cpu) / 60:.1f} (n = {len(per_trial_cpu)})"
                     if per_trial_cpu else "-")
        model_text = f"{model / 60:.1f}" if model else "-"
        cost_text = f"{median:.2f} [{q1:.2f}, {q3:.2f}]" if costs else "-"
        rate_text = "-" if rate is None else f"{rate:.2f}"
        variant_cell = f"| {variant or '-'} " if has_variants else ""
        print(f"| {method} {variant_cell}| {successes} / {n} | [{low:.2f}, {high:.2f}] | {rate_text} | "
              f"{inside} | {cost_text} | {cpu / 3600:.2f} | {per_trial}, {model_text} |")
    print(f"\nTotal CPU reported: {total_cpu / 3600:.2f} h over the attempts of "
          f"{len(completed)} completed trials (trials of builds without per-episode CPU "
          f"time count 0).\n")
    for build, trials in builds.items():
        print(f"- `{build}`: {len(trials)} trials ({', '.join(trials)})")
    print()
    if has_variants:
        print_per_seed_table(jobs, rows)
    return completed


def trial_label(job):
    variant = job.get("variant", "")
    return f"{job['method']} s{job['seed']}" + (f" {variant}" if variant else "")


def print_per_seed_table(jobs, rows):
    """Final evaluation cost per seed, one column per variant of each
    method: the paired view of a sweep over an option."""
    variants = []
    for _, variant in rows:
        if variant not in variants:
            variants.append(variant)
    methods = []
    for method, _ in rows:
        if method not in methods:
            methods.append(method)
    final = {(job["method"], job.get("variant", ""), str(job["seed"])): job
             for job in jobs if job.get("state") == "completed"}
    seeds = sorted({str(job["seed"]) for job in jobs}, key=lambda s: (len(s), s))
    print("Final evaluation cost per seed (* below the threshold; - not completed):\n")
    print("| method | seed | " + " | ".join(variants) + " |")
    print("|---|---|" + "---|" * len(variants))
    for method in methods:
        for seed in seeds:
            cells = []
            for variant in variants:
                job = final.get((method, variant, seed))
                if job is None or job.get("final_eval_cost") is None:
                    cells.append("-")
                else:
                    cells.append(f"{job['final_eval_cost']:.2f}" + ("*" if job.get("success") else ""))
            if any(cell != "-" for cell in cells):
                print(f"| {method} | {seed} | " + " | ".join(cells) + " |")
    print()


def episode_eval_costs(job):
    """Evaluation cost mean per learned episode over every attempt (a
    resumed attempt reports only the episodes after its checkpoint)."""
    costs = {}
    for attempt in job.get("attempt_log", []):
        for episode in attempt.get("episodes", []):
            costs[episode["episode"]] = episode.get("eval_cost_mean")
    return costs


def print_same_as(completed_by_archive, reference_path):
    """The determinism check: trials that repeat a reference trial exactly."""
    reference = json.load(open(reference_path))
    candidates = [job for job in reference["jobs"]
                  if job.get("kind") == "trial" and job.get("state") == "completed"]
    only_one_side = set()

    def find_match(job):
        """The reference trial whose options agree with the job's on every
        key both state, the job's swept keys among them (a coordinator of a
        later build states more of the defaults explicitly; those keys are
        listed below the table)."""
        ours = job_options(job)
        # The keys a sweep varies must be stated on both sides: a swept value
        # (particle_std) is not a default the other coordinator left implicit.
        swept = {item.split("=", 1)[0] for item in job.get("variant", "").split(",") if item}
        for candidate in candidates:
            theirs = job_options(candidate)
            shared = set(ours) & set(theirs)
            if "seed" in shared and swept <= shared and all(ours[k] == theirs[k] for k in shared):
                only_one_side.update(
                    f"{k}={ours.get(k, theirs.get(k))}" for k in set(ours) ^ set(theirs))
                return candidate
        return None

    print(f"### Repeated trials against {reference['sweep']['name']}\n")
    lines = []
    for sweep_name, completed in completed_by_archive:
        if sweep_name == reference["sweep"]["name"]:
            continue
        for job in completed:
            match = find_match(job)
            if match is None:
                continue
            ours, theirs = episode_eval_costs(job), episode_eval_costs(match)
            same_episodes = sorted(set(ours) & set(theirs))
            identical = bool(same_episodes) and set(ours) == set(theirs) and \
                all(ours[e] == theirs[e] for e in same_episodes)
            first_difference = next((e for e in same_episodes if ours[e] != theirs[e]), None)
            ours_build = (completed_attempt(job) or {}).get("worker_build", "?")
            theirs_build = (completed_attempt(match) or {}).get("worker_build", "?")
            same_build = "same build" if ours_build == theirs_build else "different builds"
            if identical:
                verdict = "identical in every episode"
            elif first_difference is None:
                verdict = "episodes reported differ"
            else:
                verdict = f"differ from episode {first_difference} on"
            lines.append(f"| {sweep_name} | {trial_label(job)} | {verdict} | "
                         f"{job['final_eval_cost']:.4f} vs {match['final_eval_cost']:.4f} | "
                         f"{same_build} |")
    if not lines:
        print("No completed trial repeats one of the reference's.\n")
        return
    print("| sweep | trial | evaluation costs | final cost (this vs reference) | builds |")
    print("|---|---|---|---|---|")
    for line in lines:
        print(line)
    print()
    if only_one_side:
        print("Options stated by only one of a matched pair (defaults the later coordinator "
              "wrote out): " + ", ".join(f"`{item}`" for item in sorted(only_one_side)) + ".\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--totalgrad", help="totalgrad binary for the cost model")
    parser.add_argument("--rerun", action="append", default=[], metavar="SWEEP=RERUN.json",
                        help="completed trials of RERUN.json replace SWEEP's same method and seed")
    parser.add_argument("--same-as", metavar="REFERENCE.json",
                        help="compare trials that repeat a completed trial of REFERENCE.json")
    parser.add_argument("archives", nargs="+")
    arguments = parser.parse_args()
    reruns = {}
    for item in arguments.rerun:
        sweep, sep, path = item.partition("=")
        if not sep or not sweep or not path:
            parser.error(f"--rerun wants SWEEP=RERUN.json, got '{item}'")
        reruns.setdefault(sweep, []).append(path)
    cache = {}
    completed_by_archive = []
    for path in arguments.archives:
        completed = report(path, arguments.totalgrad, cache, reruns)
        completed_by_archive.append((json.load(open(path))["sweep"]["name"], completed))
    if arguments.same_as:
        print_same_as(completed_by_archive, arguments.same_as)


if __name__ == "__main__":
    main()
