#!/usr/bin/env python3
"""Adds the references' agreement_resolution (core/study/study.h) to a study's
results.json written before the field existed, from a rerun of the same
study's references (same problem, seed, reference options; any estimators):
the resolution is a function of the reference replicates only, so it is
copied for a horizon only where the rerun's g* and standard errors equal the
original's bit for bit and the replicate counts match; other horizons are
left without it (and reported).

Usage: bench/add_agreement_resolution.py RESULTS_JSON RERUN_RESULTS_JSON
"""
import json
import sys


def main(results_path, rerun_path):
    with open(results_path) as f:
        results = json.load(f)
    with open(rerun_path) as f:
        rerun = json.load(f)
    by_h = {r["horizon"]: r for r in rerun["references"]}
    for ref in results["references"]:
        other = by_h.get(ref["horizon"])
        same = (other is not None and other["replicates"] == ref["replicates"]
                and other["gradient"] == ref["gradient"]
                and other["standard_error"] == ref["standard_error"])
        if same and "agreement_resolution" in other:
            # after agreement_mean_z2, where the study writes it
            items = list(ref.items())
            ref.clear()
            for key, value in items:
                if key != "agreement_resolution":
                    ref[key] = value
                if key == "agreement_mean_z2":
                    ref["agreement_resolution"] = other["agreement_resolution"]
            print(f"H = {ref['horizon']}: resolution {other['agreement_resolution']:.3g}")
        else:
            print(f"H = {ref['horizon']}: not copied (the rerun's reference differs: "
                  f"replicates {ref['replicates']} vs {other and other['replicates']})")
    with open(results_path, "w") as f:
        json.dump(results, f, indent=2, ensure_ascii=False)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
