#!/usr/bin/python3
"""Issue 16's tables from sweep archives (`totalgrad results export SWEEP -f json`).

For every method of each archive: successes / n of the completed trials, the
95% Wilson interval, the paper's rate (Table 1 of the paper, where it has one)
and whether it lies inside our interval, the median final evaluation cost with
its quartiles, the CPU hours the trials took (the per-episode CPU seconds the
workers reported) against the cost model's estimate for the same options
(`totalgrad bench estimate`), and the builds that ran the trials.

Usage: report.py [--totalgrad BIN] [--rerun SWEEP=RERUN.json]... [--reference REF.json]
                 ARCHIVE.json...
Prints Markdown on stdout. Reads nothing but the archives (and asks BIN for
the cost model, when given).

--rerun SWEEP=RERUN.json: the completed trials of the archive RERUN.json take
the place of SWEEP's trials with the same method and seed (a re-run with a
later build of trials whose build is known to be wrong); the table says which
trials were replaced. Only trials whose options agree (on the keys both
state) replace; a completed re-run that replaces nothing is named in the
report and on stderr. --merged-dir DIR writes each archive with its re-runs
in place (DIR/SWEEP.merged.json), for `results import` into a scratch
coordinator whose `results compare` and `results curves` then see them.

A sweep with task variants (options swept beside method and seed, such as
the follow-up's `normalisation`) gets one row per method and variant, and a
per-seed table of final costs side by side, variant against variant.

--reference REFERENCE.json: another sweep's archive to set these beside.
(1) The per-seed table of a sweep over an option gains a column with the
reference's trial of the same method and seed that differs in the swept
option only (the follow-up's particle_std against table1-tip-k1's default
mean_std); a mark says when the two ran on different builds. (2) The
determinism check: every completed trial whose options equal a reference
trial's is compared episode by episode (evaluation cost means); the report
says which agree bit for bit, and which builds ran the two (the same seed
gives the same trial only on the same build). Options are compared on the
keys both state (a coordinator of a later build writes out more defaults;
those keys are listed); the swept keys must be stated on both sides.
"""
import argparse
import json
import math
import os
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


def apply_reruns(sweep_name, jobs, reruns):
    """Replaces jobs by completed re-runs of the same method and seed whose
    options agree on every key both state (the re-run's coordinator may
    write out defaults the original's left implicit). The replacing job
    keeps the original's place in the sweep (job_id, sweep_name, ordinal).
    Returns (replaced labels, unmatched labels): a completed re-run that
    replaces nothing is reported, never dropped silently."""
    replaced, unmatched = [], []
    for rerun_path in reruns.get(sweep_name, []):
        rerun = json.load(open(rerun_path))
        for new in rerun["jobs"]:
            if new.get("kind") != "trial" or new.get("state") != "completed":
                continue
            label = f"{new['method']} s{new['seed']} (from {rerun['sweep']['name']})"
            for i, old in enumerate(jobs):
                if options_agree(new, old) is not None:
                    merged = dict(new)
                    for key in ("job_id", "sweep_name", "ordinal"):
                        if key in old:
                            merged[key] = old[key]
                    jobs[i] = merged
                    replaced.append(label)
                    break
            else:
                unmatched.append(label)
    return replaced, unmatched


def report(archive_path, binary, cache, reruns, reference=None, merged_dir=None):
    archive = json.load(open(archive_path))
    sweep = archive["sweep"]
    jobs = [job for job in archive["jobs"] if job.get("kind") == "trial"]
    replaced, unmatched = apply_reruns(sweep["name"], jobs, reruns)
    if merged_dir:
        # The sweep with its re-runs in place, as an archive that `results
        # import` takes, so the service's own compare and curves see them.
        merged = dict(archive)
        merged["jobs"] = [job for job in archive["jobs"] if job.get("kind") != "trial"] + jobs
        with open(os.path.join(merged_dir, f"{sweep['name']}.merged.json"), "w") as f:
            json.dump(merged, f)
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
    if unmatched:
        message = (f"Re-run trials that match no trial of this sweep (not used): "
                   f"{', '.join(unmatched)}.")
        print(f"**{message}**\n")
        print(f"report.py: {sweep['name']}: {message}", file=sys.stderr)
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
        print_per_seed_table(jobs, rows, reference)
    return sweep["name"], completed


def swept_keys(job):
    return {item.split("=", 1)[0] for item in job.get("variant", "").split(",") if item}


def options_agree(job, candidate, ignore=()):
    """Whether two trials' options agree on every key both state, ignoring
    `ignore`; the keys `job` sweeps must be stated by both (a swept value
    such as particle_std is not a default the other coordinator left
    implicit). Returns the keys only one side states, or None."""
    ours, theirs = job_options(job), job_options(candidate)
    shared = set(ours) & set(theirs)
    if "seed" not in shared or not swept_keys(job) <= shared:
        return None
    if any(ours[k] != theirs[k] for k in shared if k not in ignore):
        return None
    return {f"{k}={ours.get(k, theirs.get(k))}" for k in set(ours) ^ set(theirs)}


def completed_trials(archive):
    return [job for job in archive["jobs"]
            if job.get("kind") == "trial" and job.get("state") == "completed"]


def trial_label(job):
    variant = job.get("variant", "")
    return f"{job['method']} s{job['seed']}" + (f" {variant}" if variant else "")


def cost_cell(job):
    if job is None or job.get("final_eval_cost") is None:
        return "-"
    return f"{job['final_eval_cost']:.2f}" + ("*" if job.get("success") else "")


def reference_counterpart(job, reference):
    """The reference's completed trial that differs from `job` in the swept
    options only (same method and seed), or None."""
    for candidate in completed_trials(reference):
        if options_agree(job, candidate, ignore=swept_keys(job)) is not None:
            return candidate
    return None


def print_per_seed_table(jobs, rows, reference=None):
    """Final evaluation cost per seed, one column per variant of each
    method: the paired view of a sweep over an option; with a reference,
    first a column of the reference's counterpart trials."""
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
    print("Final evaluation cost per seed (* below the threshold; - not completed"
          + ("; + the reference trial ran on another build than this sweep's" if reference
             else "") + "):\n")
    reference_header = []
    if reference is not None:
        keys = sorted({key for job in jobs for key in swept_keys(job)})
        values = []
        for candidate in completed_trials(reference):
            options = job_options(candidate)
            value = ",".join(f"{k}={options.get(k, '?')}" for k in keys)
            if value not in values:
                values.append(value)
        reference_header = [f"{reference['sweep']['name']}: {', '.join(values)}"]
    columns = reference_header + variants
    print("| method | seed | " + " | ".join(columns) + " |")
    print("|---|---|" + "---|" * len(columns))
    for method in methods:
        for seed in seeds:
            cells = []
            ours = [final.get((method, variant, seed)) for variant in variants]
            if reference is not None:
                anchor = next((job for job in jobs if job["method"] == method and
                               str(job["seed"]) == seed), None)
                counterpart = reference_counterpart(anchor, reference) if anchor else None
                mark = ""
                builds = {(completed_attempt(job) or {}).get("worker_build")
                          for job in ours if job is not None}
                if counterpart is not None and builds and \
                        (completed_attempt(counterpart) or {}).get("worker_build") not in builds:
                    mark = "+"
                cells.append(cost_cell(counterpart) + mark)
            cells += [cost_cell(job) for job in ours]
            if any(cell != "-" for cell in cells[len(reference_header):]):
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


def print_repeats(completed_by_archive, reference):
    """The determinism check: trials that repeat a reference trial exactly."""
    only_one_side = set()

    def find_match(job):
        for candidate in completed_trials(reference):
            one_sided = options_agree(job, candidate)
            if one_sided is not None:
                only_one_side.update(one_sided)
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
    parser.add_argument("--reference", metavar="REFERENCE.json",
                        help="set trials beside REFERENCE.json's: per-seed counterparts of a "
                             "swept option, and exact repeats")
    parser.add_argument("--merged-dir", metavar="DIR",
                        help="write each archive with its re-runs in place to DIR/SWEEP.merged.json")
    parser.add_argument("archives", nargs="+")
    arguments = parser.parse_args()
    reruns = {}
    for item in arguments.rerun:
        sweep, sep, path = item.partition("=")
        if not sep or not sweep or not path:
            parser.error(f"--rerun wants SWEEP=RERUN.json, got '{item}'")
        reruns.setdefault(sweep, []).append(path)
    cache = {}
    reference = json.load(open(arguments.reference)) if arguments.reference else None
    completed_by_archive = []
    for path in arguments.archives:
        completed_by_archive.append(report(path, arguments.totalgrad, cache, reruns, reference,
                                           arguments.merged_dir))
    if reference is not None:
        print_repeats(completed_by_archive, reference)


if __name__ == "__main__":
    main()
