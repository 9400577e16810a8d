#!/usr/bin/python3
"""Total propagation's LR share per time step of the horizon, averaged over
the learned episodes of a sweep's completed trials, per method: the profile
docs/diagnostics.md's worked example reads.

Usage: lr_share_profile.py DATABASE SWEEP   (read-only; Debian's python3)
"""
import json
import sqlite3
import sys

database, sweep = sys.argv[1], sys.argv[2]
db = sqlite3.connect(f"file:{database}?mode=ro", uri=True)
rows = db.execute(
    """SELECT j.method, e.lr_share_json FROM episodes e JOIN jobs j ON j.id = e.job_id
       JOIN sweeps s ON s.id = j.sweep_id
       WHERE s.name = ? AND j.state = 'completed' AND e.attempt = j.completed_attempt
         AND e.lr_share_json IS NOT NULL AND e.lr_share_json != '[]'""", (sweep,))
profiles = {}
for method, text in rows:
    profiles.setdefault(method, []).append(json.loads(text))
steps = (1, 5, 10, 15, 20, 25, 30)
print("method  episodes  " + "  ".join(f"t={t:<4}" for t in steps))
for method, lists in profiles.items():
    mean = [sum(v[t] for v in lists) / len(lists) for t in range(len(lists[0]))]
    print(f"{method:7s} {len(lists):8d}  " + "  ".join(f"{mean[t - 1]:.3f} " for t in steps if t <= len(mean)))
