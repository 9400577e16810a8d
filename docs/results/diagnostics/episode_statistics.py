#!/usr/bin/python3
"""Per completed trial of a sweep, per learned episode: the evaluation cost
and the optimisation statistics docs/diagnostics.md's DEL-against-RP example
reads (mean gradient norm, mean SNR, mean step norm), one line per trial and
quantity.

Usage: episode_statistics.py DATABASE SWEEP   (read-only; Debian's python3)
"""
import sqlite3
import sys

database, sweep = sys.argv[1], sys.argv[2]
db = sqlite3.connect(f"file:{database}?mode=ro", uri=True)
jobs = db.execute(
    """SELECT j.id, j.method, j.seed, j.final_eval_cost FROM jobs j JOIN sweeps s ON s.id = j.sweep_id
       WHERE s.name = ? AND j.state = 'completed' ORDER BY j.ordinal""", (sweep,)).fetchall()
quantities = (("evaluation cost", "eval_cost_mean", "{:.1f}"),
              ("gradient norm, mean", "gradient_norm_mean", "{:.3g}"),
              ("SNR, mean", "gradient_snr_mean", "{:.2g}"),
              ("step norm, mean", "step_norm_mean", "{:.3f}"))
print(f"sweep {sweep}: learned episodes 1, 2, ... of each completed trial")
for job_id, method, seed, final in jobs:
    print(f"{method} seed {seed} (final evaluation {final:.3f})")
    for label, column, form in quantities:
        values = db.execute(
            f"""SELECT e.{column} FROM episodes e JOIN jobs j ON j.id = e.job_id
                WHERE j.id = ? AND e.attempt = j.completed_attempt AND e.episode > 0
                ORDER BY e.episode""", (job_id,)).fetchall()
        print(f"  {label:20s} " + " ".join("-" if v is None else form.format(v) for (v,) in values))
