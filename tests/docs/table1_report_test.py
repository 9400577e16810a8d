#!/usr/bin/python3
"""docs/results/table1/report.py on synthetic sweep archives: one row per
method and task variant, the per-seed table of a swept option, and the
the reference sweep (--reference): its counterpart trials in the per-seed
table, and the determinism check that tells identical repeats from trials that
differ, naming the first differing episode.

Usage: table1_report_test.py REPORT_PY
"""
import json
import os
import subprocess
import sys
import tempfile

BUILD_A = "totalgrad test build A"
BUILD_B = "totalgrad test build B"


def trial(method, seed, variant, costs, build, success=None, extra_options=()):
    """A completed trial job as `results export -f json` writes it."""
    options = [["method", method], ["seed", str(seed)], ["scene", "cartpole-swingup"],
               ["cost", "tip"], ["noise_k", "1"]]
    if variant:
        key, value = variant.split("=")
        options.append([key, value])
    options += [list(item) for item in extra_options]
    episodes = [{"episode": e, "eval_cost_mean": c, "cpu_seconds": 60.0}
                for e, c in enumerate(costs)]
    final = costs[-1]
    return {"kind": "trial", "method": method, "seed": seed, "variant": variant,
            "options": options, "state": "completed",
            "success": final < 15 if success is None else success,
            "final_eval_cost": final, "completed_attempt": 1,
            "attempt_log": [{"attempt": 1, "worker_build": build, "episodes": episodes}]}


def queued(method, seed, variant):
    job = trial(method, seed, variant, [0.0], BUILD_A)
    job.update(state="queued", success=False, final_eval_cost=None, completed_attempt=0,
               attempt_log=[])
    return job


def archive(name, jobs):
    return {"format": "totalgrad-sweep-archive", "version": 3, "exported_by": "test",
            "exported_unix_ms": 0, "sweep": {"name": name, "description": name}, "jobs": jobs}


def run(report_py, directory, archives, *arguments):
    paths = []
    for name, content in archives:
        path = os.path.join(directory, name + ".json")
        with open(path, "w") as f:
            json.dump(content, f)
        paths.append(path)
    result = subprocess.run([sys.executable, report_py, *arguments, *paths],
                            capture_output=True, text=True)
    if result.returncode != 0:
        raise AssertionError(f"report.py failed: {result.stderr}")
    return result.stdout, paths


def expect(condition, message, output):
    if not condition:
        raise AssertionError(f"{message}\n--- output ---\n{output}")


def main():
    report_py = sys.argv[1]
    with tempfile.TemporaryDirectory() as directory:
        # The main sweep states the default normalisation, except for one
        # trial (RP 13) whose options leave it out.
        stated = [("normalisation", "mean_std")]
        reference = archive("main", [
            trial("RP", 11, "", [30.0, 29.0, 12.5], BUILD_A, extra_options=stated),
            trial("RP", 12, "", [30.0, 28.0, 27.0], BUILD_A, extra_options=stated),
            trial("RP", 13, "", [30.0, 28.0, 28.0], BUILD_A),
            trial("GTP", 11, "", [30.0, 20.0, 9.0], BUILD_B, extra_options=stated),
        ])
        # The follow-up sweeps `normalisation`; its coordinator wrote out a
        # default the main sweep's left implicit (matched on shared keys).
        extra = [("gravity", "9.82")]

        def followup_trial(method, seed, normalisation, costs):
            return trial(method, seed, f"normalisation={normalisation}", costs, BUILD_A,
                         extra_options=extra)

        followup = archive("followup", [
            followup_trial("RP", 11, "mean_std", [30.0, 29.0, 12.5]),
            followup_trial("RP", 11, "particle_std", [30.0, 29.5, 28.0]),
            followup_trial("RP", 12, "mean_std", [30.0, 28.0, 26.0]),
            queued("RP", 12, "normalisation=particle_std"),
            # Same numbers as main's RP 13, which does not state the swept
            # key: no repeat (a swept value is not an implicit default).
            followup_trial("RP", 13, "particle_std", [30.0, 28.0, 28.0]),
            followup_trial("GTP", 11, "mean_std", [30.0, 20.0, 9.0]),
            followup_trial("GTP", 11, "particle_std", [30.0, 18.0, 7.0]),
        ])
        output, paths = run(report_py, directory, [("main", reference), ("followup", followup)],
                            "--reference", os.path.join(directory, "main.json"))

        # One row per method and variant, with its own counts.
        expect("| RP | normalisation=mean_std | 1 / 2 |" in output,
               "RP mean_std row: 1 success of 2", output)
        expect("| RP | normalisation=particle_std | 0 / 2 |" in output,
               "RP particle_std row: 0 of 2 (the queued trial is not counted)", output)
        expect("| GTP | normalisation=particle_std | 1 / 1 |" in output,
               "GTP particle_std row", output)
        # A sweep without variants keeps the method-only table.
        expect("| RP | 1 / 3 |" in output, "the main sweep's rows have no variant column",
               output)

        # The per-seed table puts the variants side by side after the
        # reference's counterpart (same method and seed, differing in the
        # swept option only), marks successes, leaves the queued trial as
        # "-", marks a counterpart of another build with "+", and finds no
        # counterpart for RP 13, whose reference trial does not state the
        # swept key.
        expect("| method | seed | main: normalisation=mean_std" in output,
               "reference column header", output)
        expect("| RP | 11 | 12.50* | 12.50* | 28.00 |" in output, "per-seed row RP 11", output)
        expect("| RP | 12 | 27.00 | 26.00 | - |" in output, "per-seed row RP 12", output)
        expect("| RP | 13 | - | - | 28.00 |" in output, "per-seed row RP 13", output)
        expect("| GTP | 11 | 9.00*+ | 9.00* | 7.00* |" in output, "per-seed row GTP 11", output)

        # Determinism check: RP 11 repeats the main trial exactly on the same
        # build; RP 12 differs from its last episode; GTP 11 matches in
        # numbers but ran on another build, which the row says.
        expect("| followup | RP s11 normalisation=mean_std | identical in every episode | "
               "12.5000 vs 12.5000 | same build |" in output, "identical repeat", output)
        expect("| followup | RP s12 normalisation=mean_std | differ from episode 2 on | "
               "26.0000 vs 27.0000 | same build |" in output, "differing repeat", output)
        expect("| followup | GTP s11 normalisation=mean_std | identical in every episode | "
               "9.0000 vs 9.0000 | different builds |" in output, "build difference named",
               output)
        expect("particle_std | identical" not in output and
               "particle_std | differ" not in output,
               "a trial with another normalisation, stated or not, is no repeat", output)
        expect("`gravity=9.82`" in output, "keys stated on one side only are listed", output)

        # A reference without any match says so instead of an empty table.
        output, _ = run(report_py, directory,
                        [("other", archive("other", [trial("LR", 3, "", [1.0], BUILD_A)]))],
                        "--reference", paths[0])
        expect("No completed trial repeats one of the reference's." in output,
               "no-match message", output)
        check_reruns(report_py, directory)
    print("table1 report: all checks passed")


def check_reruns(report_py, directory):
    """--rerun puts a re-run in the place of the trial with the same method,
    seed and options, even when the re-run's coordinator wrote out defaults
    the original's left implicit; a re-run that matches nothing is named;
    --merged-dir writes the merged sweep for `results import`."""
    original = archive("main", [
        trial("PILCO", 10, "", [30.0, 29.9], BUILD_A),
        trial("PILCO", 11, "", [30.0, 13.0], BUILD_A),
        trial("RP", 10, "", [30.0, 29.0], BUILD_A),
    ])
    original["jobs"][0]["job_id"] = 7
    rerun = archive("main-rerun", [
        trial("PILCO", 10, "", [30.0, 12.0], BUILD_B, extra_options=[("gravity", "9.82")]),
        trial("PILCO", 12, "", [30.0, 11.0], BUILD_B),
    ])
    rerun["jobs"][0]["job_id"] = 99
    rerun_path = os.path.join(directory, "main-rerun.json")
    with open(rerun_path, "w") as f:
        json.dump(rerun, f)
    merged_dir = os.path.join(directory, "merged")
    os.mkdir(merged_dir)
    output, _ = run(report_py, directory, [("main", original)],
                    "--rerun", f"main={rerun_path}", "--merged-dir", merged_dir)
    expect("Re-run trials in place of this sweep's own: PILCO s10 (from main-rerun)." in output,
           "the re-run with extra stated defaults replaces PILCO s10", output)
    expect("| PILCO | 2 / 2 |" in output, "PILCO counts the re-run's success", output)
    expect("match no trial of this sweep (not used): PILCO s12 (from main-rerun)" in output,
           "an unmatched re-run is named", output)
    merged = json.load(open(os.path.join(merged_dir, "main.merged.json")))
    pilco10 = [job for job in merged["jobs"] if job["method"] == "PILCO" and job["seed"] == 10]
    expect(len(pilco10) == 1 and pilco10[0]["final_eval_cost"] == 12.0 and
           pilco10[0]["job_id"] == 7 and len(merged["jobs"]) == 3,
           "merged archive: the re-run in the original's place, keeping its job id",
           json.dumps(merged["jobs"])[:2000])


if __name__ == "__main__":
    main()
