#!/bin/bash
# Brings issue 25's Table-1 runs back on a machine where they are not running
# (a new session, a fresh machine): builds the workers' build if it is
# missing, starts a coordinator on a new file, imports every committed
# archive of docs/results/table1/, puts the PILCO re-runs in their places in
# table1-tip-k1 (`job supersede`, by seed: ids differ per import), and starts
# two niced workers. What the runs were doing when last exported comes back
# with the archives: queued and paused jobs as they were; a job running at
# export time starts over (its checkpoint was on the old machine).
#
#   restart_issue25.sh RUN_DIR [--build COMMIT] [--port PORT] [--workers N]
#
# RUN_DIR (created if missing) holds t1.db, the token files, the logs, the
# workers' state and bin-COMMIT/ (the CLI, coordinator and worker of COMMIT,
# default 8abc303, built from a git worktree of this repository when absent).
# The coordinator listens on 127.0.0.1:PORT (default 7171; HTTP on PORT+1).
# --workers 0 starts none (to check an import). Refuses to run when RUN_DIR
# already has a t1.db: an existing coordinator file is never replaced.
# Afterwards: `sweep list`, `sweep resume NAME` for paused sweeps (see
# table1.md's last export for which), and export_issue25.sh before stopping.
set -euo pipefail
usage() { echo "usage: restart_issue25.sh RUN_DIR [--build COMMIT] [--port PORT] [--workers N]" >&2; exit 2; }
[ $# -ge 1 ] || usage
run_dir=$1; shift
commit=8abc303; port=7171; workers=2
while [ $# -gt 0 ]; do
  case $1 in
    --build) commit=${2:?}; shift 2 ;;
    --port) port=${2:?}; shift 2 ;;
    --workers) workers=${2:?}; shift 2 ;;
    *) usage ;;
  esac
done
here=$(cd "$(dirname "$0")" && pwd)
repo=$(git -C "$here" rev-parse --show-toplevel)
mkdir -p "$run_dir"; run_dir=$(cd "$run_dir" && pwd)
if [ -e "$run_dir/t1.db" ]; then
  echo "restart_issue25.sh: $run_dir/t1.db exists; start its coordinator instead (table1.md, 'How it runs')" >&2
  exit 1
fi
bin="$run_dir/bin-$commit"
if [ ! -x "$bin/totalgrad-worker" ]; then
  src="$run_dir/src-$commit"
  [ -d "$src" ] || git -C "$repo" worktree add --detach "$src" "$commit"
  cmake -S "$src" -B "$src/build" -G Ninja -DCMAKE_BUILD_TYPE=Release \
      -DTOTALGRAD_BUILD_TESTS=OFF -DTOTALGRAD_BUILD_BENCHMARKS=OFF > "$run_dir/build-$commit.log"
  cmake --build "$src/build" -j "$(nproc)" --target totalgrad totalgrad-coordinator totalgrad-worker \
      >> "$run_dir/build-$commit.log"
  mkdir -p "$bin"
  cp "$src/build/client/totalgrad" "$src/build/server/totalgrad-coordinator" \
     "$src/build/worker/totalgrad-worker" "$bin/"
fi
cd "$run_dir"
for role in worker user; do
  [ -s $role.token ] || (umask 077 && head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' > $role.token)
done
export TOTALGRAD_TOKEN_FILE=$run_dir/user.token
cli() { "$bin/totalgrad" "$@" --coordinator "127.0.0.1:$port" --insecure; }

setsid nohup "$bin/totalgrad-coordinator" --db t1.db --listen "127.0.0.1:$port" --insecure \
    --http-listen "127.0.0.1:$((port + 1))" --worker-token-file worker.token \
    --user-token-file user.token >> "coordinator-$commit.log" 2>&1 &
for _ in $(seq 50); do cli sweep list > /dev/null 2>&1 && break; sleep 0.2; done
cli sweep list > /dev/null

# The sweeps the others' results depend on first; every archive that exists.
for sweep in table1-tip-k1 table1-tip-k1-pilco-rerun balance-del table1-followup-particle-std \
             table1-tip-k001 table1-tip-k1-rest table1-tip-k1-rerun; do
  [ -f "$here/$sweep.archive.json" ] && cli results import "$here/$sweep.archive.json"
done
[ -f "$repo/docs/results/diagnostics/diag-balance-del-rp.archive.json" ] &&
  cli results import "$repo/docs/results/diagnostics/diag-balance-del-rp.archive.json"

# table1-tip-k1's PILCO seeds 10 and 11 count their re-runs (table1.md). The
# archive exported since 2026-11-30 carries the supersessions already; a
# coordinator of 8abc303 would add a second copy if told again, so only a job
# whose final cost is not yet its re-run's is superseded.
job_field() {  # SWEEP METHOD SEED FIELD -> the job's FIELD
  cli job list --sweep "$1" -f json | /usr/bin/python3 -c '
import json, sys
method, seed, field = sys.argv[1], sys.argv[2], sys.argv[3]
jobs = [j for j in json.load(sys.stdin) if j["method"] == method and str(j["seed"]) == seed]
if len(jobs) != 1: sys.exit(f"expected one {method} seed {seed}, found {len(jobs)}")
print(jobs[0][field])' "$2" "$3" "$4"
}
for seed in 10 11; do
  if [ "$(job_field table1-tip-k1 PILCO $seed final_eval_cost)" != \
       "$(job_field table1-tip-k1-pilco-rerun PILCO $seed final_eval_cost)" ]; then
    cli job supersede "$(job_field table1-tip-k1 PILCO $seed job_id)" \
        --by "$(job_field table1-tip-k1-pilco-rerun PILCO $seed job_id)"
  fi
done

for n in $(seq "$workers"); do
  setsid nohup nice -n 19 "$bin/totalgrad-worker" --coordinator "127.0.0.1:$port" --insecure \
      --token-file worker.token --slots 1 --worker-id "t1-w$n" --state-dir "state-w$n" \
      >> "worker-w$n.log" 2>&1 &
  sleep 1
  # nice orders processes only within their session's autogroup (table1.md).
  echo 19 > "/proc/$!/autogroup" 2>/dev/null || echo "note: could not nice worker $n's autogroup" >&2
done
cli sweep list
