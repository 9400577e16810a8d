#!/bin/bash
# Puts each completed trial of table1-tip-k1-rerun in its place in
# table1-tip-k1 (`totalgrad job supersede`, matched by method and seed, since
# job ids differ per import), so that table1-tip-k1 counts the re-run: the
# same costs bit for bit (table1.md checks each), plus the rollout verdict and
# the kept final checkpoint the original trials lack.
#
#   supersede_k1_by_rerun.sh CLI COORDINATOR
#
# CLI is the `totalgrad` binary to call, COORDINATOR host:port (plaintext);
# the user token comes from TOTALGRAD_TOKEN_FILE. Both sweeps must be on the
# coordinator. Idempotent: a table1-tip-k1 job that already has a held
# fraction (it counts its re-run) is left alone, because a coordinator of
# build 8abc303 adds a second copy of the re-run's attempt when told again.
# Prints one line per supersession and a count.
#
# Export table1-tip-k1 afterwards only from a coordinator of the current
# build (8abc303 fills an imported trial's options with its own defaults):
# import table1-tip-k1 and table1-tip-k1-rerun into a scratch coordinator,
# run this, then `results export table1-tip-k1 -f json --checkpoints`.
set -euo pipefail
cli_binary=${1:?usage: supersede_k1_by_rerun.sh CLI COORDINATOR}
coordinator=${2:?usage: supersede_k1_by_rerun.sh CLI COORDINATOR}
cli() { "$cli_binary" "$@" --coordinator "$coordinator" --insecure; }

# Pairs "ORIGINAL_ID RERUN_ID" for every completed re-run whose original does
# not count it yet; fails when a method and seed is not exactly one job.
pairs=$(/usr/bin/python3 - <(cli job list --sweep table1-tip-k1 -f json) \
                          <(cli job list --sweep table1-tip-k1-rerun -f json) <<'EOF'
import json, math, sys

def by_trial(path):
    jobs = {}
    for job in json.load(open(path)):
        key = (job["method"], str(job["seed"]))
        if key in jobs:
            sys.exit(f"two jobs for {key[0]} seed {key[1]} in {job['sweep_name']}")
        jobs[key] = job
    return jobs

def has_verdict(job):
    value = job.get("held_fraction")
    return value is not None and not (isinstance(value, float) and math.isnan(value))

originals, reruns = by_trial(sys.argv[1]), by_trial(sys.argv[2])
for key, rerun in sorted(reruns.items()):
    if rerun["state"] != "completed":
        continue
    original = originals.get(key)
    if original is None:
        sys.exit(f"table1-tip-k1 has no {key[0]} seed {key[1]} for its re-run")
    if original["state"] == "completed" and not has_verdict(original):
        print(original["job_id"], rerun["job_id"])
EOF
)
count=0
while read -r original rerun; do
  [ -n "$original" ] || continue
  cli job supersede "$original" --by "$rerun"
  count=$((count + 1))
done <<< "$pairs"
echo "superseded $count table1-tip-k1 trials by their re-runs"
