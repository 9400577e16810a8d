#!/usr/bin/env python3
"""The unicycle tables of docs/results/scenes.md from the committed archives.

    python3 docs/results/scenes/unicycle_tables.py [--summary] docs/results/scenes/unicycle-*.archive.json

For each job, the episodes of the attempt that holds each one (the latest
attempt that stored it: a resumed attempt copies the earlier episodes), the
evaluation means, the final rollout verdict, the CPU seconds summed over the
episodes, and for TP its gradient's mean SNR and median ESS per episode.
"""
import json
import sys


def episodes_of(job):
    """Episode number -> record, the latest attempt's where several hold it."""
    by_episode = {}
    for attempt in sorted(job["attempt_log"], key=lambda a: a["attempt"]):
        for e in attempt["episodes"]:
            by_episode[e["episode"]] = e
    return [by_episode[k] for k in sorted(by_episode)]


def variant_text(variant):
    """'learning_rate=0.00050000000000000001' -> 'learning_rate=0.0005'."""
    if not variant:
        return "-"
    out = []
    for pair in variant.split(","):
        key, _, value = pair.partition("=")
        try:
            value = f"{float(value):g}"
        except ValueError:
            pass
        out.append(f"{key}={value}")
    return ", ".join(out)


def fmt(x, digits=2):
    return "-" if x is None else f"{x:.{digits}f}"


def summary(paths):
    """One row per job: evaluation means after learned episodes 1, 5, 10, 15,
    20, 30, 40 (those it has), the final verdict and the CPU seconds."""
    marks = [1, 5, 10, 15, 20, 30, 40]
    print("| sweep | method | variant | " + " | ".join(f"ep {m}" for m in marks) +
          " | held (final) | learned episodes | CPU s |")
    print("|---|---|---|" + "---|" * len(marks) + "---|---|---|")
    for path in paths:
        archive = json.load(open(path))
        for job in archive["jobs"]:
            eps = {e["episode"]: e for e in episodes_of(job)}
            cells = [fmt(eps[m]["eval_cost_mean"]) if m in eps else "" for m in marks]
            learned = max(eps) if eps else 0
            held = eps[learned]["held_fraction"] if learned in eps else None
            cpu = sum(e["cpu_seconds"] or 0 for e in eps.values())
            print(f"| {archive['sweep']['name']} | {job['method']} | {variant_text(job['variant'])} | " +
                  " | ".join(cells) + f" | {fmt(held)} | {learned} of "
                  f"{job['episodes_expected'] - 1} | {cpu:.0f} |")


def main(paths):
    if paths and paths[0] == "--summary":
        summary(paths[1:])
        return
    for path in paths:
        archive = json.load(open(path))
        for job in archive["jobs"]:
            eps = episodes_of(job)
            learned = [e for e in eps if e["episode"] > 0]
            variant = variant_text(job["variant"])
            cpu = sum(e["cpu_seconds"] or 0 for e in eps)
            last = learned[-1] if learned else None
            print(f"## {archive['sweep']['name']} job {job['job_id']}: {job['method']} seed "
                  f"{job['seed']} {variant}, {job['state']}, {len(learned)} of "
                  f"{job['episodes_expected'] - 1} learned episodes, {cpu:.0f} CPU s")
            print("| episode | real cost | evaluation mean | predicted | CPU s | SNR mean | ESS median | held |")
            print("|---|---|---|---|---|---|---|---|")
            for e in eps:
                print(f"| {e['episode']} | {fmt(e['real_cost'])} | {fmt(e['eval_cost_mean'])} | "
                      f"{fmt(e['predicted_cost'])} | {fmt(e['cpu_seconds'], 1)} | "
                      f"{fmt(e['gradient_snr_mean'])} | {fmt(e['ess_median'], 1)} | "
                      f"{fmt(e['held_fraction'])} |")
            if last is not None and job["state"] == "completed":
                print(f"final evaluation {fmt(last['eval_cost_mean'])}, held fraction "
                      f"{fmt(last['held_fraction'])}, success (threshold) {job['success']}")
            print()


if __name__ == "__main__":
    main(sys.argv[1:])
