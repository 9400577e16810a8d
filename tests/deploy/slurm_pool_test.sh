#!/usr/bin/env bash
# deploy/slurm/totalgrad-workers.sbatch run as Slurm would run it, without
# Slurm: stand-in `srun` (runs the task once, as task 0, and forwards SIGTERM
# to it like srun does) and `squeue` (prints the time left), with the real
# worker against a real coordinator (TLS and tokens, on 127.0.0.1).
#
#   A. Walltime: 12 s left, trials of at most 6 s. The worker takes tiny
#      trials for 6 s, then drains and exits; the script exits 0 well before
#      the limit; every trial the worker took completed (none released or
#      lost) and trials it could not have finished stay queued.
#   B. No time limit known (squeue says UNLIMITED): SIGTERM to the batch
#      script (what --signal=B:TERM@300 and `scancel --signal=TERM --batch`
#      send) reaches the worker, which drains and exits 0.
#   C. SIGTERM before srun (Slurm sends --signal=B:TERM@300 at once to a job
#      with less than 300 s left): no worker starts, the script exits 0.
# Plus the script's duration parser on Slurm's time formats.
#
#   slurm_pool_test.sh COORDINATOR_BIN WORKER_BIN CLI_BIN SOURCE_DIR
set -euo pipefail

if [ $# -ne 4 ]; then
  echo "usage: $0 COORDINATOR_BIN WORKER_BIN CLI_BIN SOURCE_DIR" >&2
  exit 2
fi
coordinator_bin=$1 worker_bin=$2 cli_bin=$3 source_dir=$4
sbatch_script="$source_dir/deploy/slurm/totalgrad-workers.sbatch"

# shellcheck source=tests/deploy/test_helpers.sh
source "$(dirname "${BASH_SOURCE[0]}")/test_helpers.sh"

work=$(mktemp -d /tmp/totalgrad-slurm.XXXXXX)
pids=()
cleanup() {
  local status=$?
  trap - EXIT
  for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null || true; done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
  if [ "$status" -ne 0 ]; then
    show_logs "$work"
  fi
  rm -rf "$work"
  exit "$status"
}
trap cleanup EXIT


# ---- the duration parser ---------------------------------------------------------------
# shellcheck source=/dev/null
(
  source "$sbatch_script"
  for case in "1-00:00:00=86400" "12:00:00=43200" "05:30=330" "90=5400" "2-3=183600" \
              "2-03:04=183840" "00:00:09=9" "0:08=8" "UNLIMITED=" "NOT_SET=" "=" "1:2:3:4="; do
    input=${case%=*} expected=${case#*=}
    got=$(slurm_duration_seconds "$input" || true)
    [ "$got" = "$expected" ] || { echo "FAIL: slurm_duration_seconds '$input' = '$got', expected '$expected'"; exit 1; }
  done
) || exit 1
log "duration parser: 12 Slurm time formats"

# ---- coordinator ---------------------------------------------------------------------------
start_tls_coordinator "$coordinator_bin" "$source_dir" "$work"
cli() { TOTALGRAD_TOKEN_FILE="$work/certs/user.token" "$cli_bin" "$@"; }

cat >"$work/pool.toml" <<'EOF'
name = "slurm-pool"
[grid]
method = ["RP"]
seed = { first = 1, count = 400 }
[protocol]
episodes = 2
policy_steps = 3
particles = 8
eval_rollouts = 2
horizon = 10
EOF
cli sweep submit "$work/pool.toml" >/dev/null

# ---- stand-ins for srun and squeue ------------------------------------------------------
mkdir -p "$work/bin"
cat >"$work/bin/srun" <<'EOF'
#!/bin/bash
# Stand-in srun: records its arguments, runs the task once as task 0 and
# forwards SIGTERM to it (srun forwards signals to the tasks it controls).
printf '%s\n' "$@" >"$FAKE_SLURM_DIR/srun.args"
echo "OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-unset}" >"$FAKE_SLURM_DIR/srun.env"
while [[ $# -gt 0 && "$1" == --* ]]; do shift; done
export SLURM_PROCID=0 SLURM_STEP_ID=0
"$@" &
task=$!
trap 'kill -TERM "$task" 2>/dev/null' TERM
status=0
while kill -0 "$task" 2>/dev/null; do wait "$task" && status=0 || status=$?; done
exit "$status"
EOF
cat >"$work/bin/squeue" <<'EOF'
#!/bin/bash
touch "$FAKE_SLURM_DIR/squeue.called"
sleep "${FAKE_SQUEUE_DELAY:-0}"
echo "$FAKE_TIME_LEFT"
EOF
chmod +x "$work/bin/srun" "$work/bin/squeue"

run_sbatch() {  # run_sbatch TIME_LEFT OUTPUT [SQUEUE_DELAY]: the batch script in the background
  env PATH="$work/bin:$PATH" FAKE_SLURM_DIR="$work" FAKE_TIME_LEFT="$1" FAKE_SQUEUE_DELAY="${3:-0}" \
    SLURM_JOB_ID=4242 SLURM_JOB_NUM_NODES=1 SLURM_CPUS_PER_TASK=1 \
    TOTALGRAD_WORKER_BIN="$worker_bin" TOTALGRAD_WORKER_TOKEN_FILE="$work/certs/worker.token" \
    TOTALGRAD_TRIAL_TIME=6 \
    bash "$sbatch_script" >"$2" 2>&1 &
  pids+=("$!")
}
jobs_query() {  # jobs_query PYTHON_EXPRESSION over `jobs`: prints its value
  cli job list --sweep slurm-pool -f json | python3 -c "
import json, sys
jobs = json.load(sys.stdin)
print($1)"
}

# After a drain nothing may stay running and no lease may be charged, with
# one exception. The drain cancels the worker's waiting AcquireLease; if the
# coordinator granted a lease in that instant, it notices the cancellation and
# returns the job uncharged (no lost lease); if the grant reached the worker,
# the worker gives it back marked never_started, also uncharged (CI once saw
# this release charged: "job N attempt 1: released (drain)" with no trial
# started, failing B). Only if the cancellation lands
# after that check, while the answer is on its way, does the job stay running
# until its lease expires (5 s here) and come back with one lost lease. Such a
# job must never have reached the worker; anything else still running, or any
# other lost lease, fails the test.
check_after_drain() {  # check_after_drain LABEL WORKER_OUTPUT
  local label=$1 output=$2 running stranded lost job
  running=$(jobs_query "sum(j['state'] == 'running' for j in jobs)")
  if [ "$running" -gt 0 ]; then
    stranded=$(jobs_query "[j['job_id'] for j in jobs if j['state'] == 'running']")
    log "$label: note: job(s) $stranded still running after the worker exited: a lease granted to the cancelled poll"
    for job in $(echo "$stranded" | tr -d '[],'); do
      if grep -q "job $job attempt" "$output"; then fail "job $job reached the worker but was not ended"; fi
    done
    none_running() { [ "$(jobs_query "sum(j['state'] == 'running' for j in jobs)")" = 0 ]; }
    wait_for 30 "the stranded lease to expire" none_running
    log "$label: the stranded lease expired and its job was re-queued"
  fi
  lost=$(jobs_query "sum(j['lost_leases'] for j in jobs)")
  [ "$lost" -le $(( lost_before + running )) ] || fail "$label: a trial was released or lost ($lost lost leases)"
  lost_before=$lost
}
lost_before=0

# ---- A: the walltime ----------------------------------------------------------------------
started=$(date +%s%N)
run_sbatch 0:12 "$work/walltime.out"
sbatch_pid=${pids[-1]}
wait_for 30 "the batch script to end (walltime)" exited "$sbatch_pid"
status=0
wait "$sbatch_pid" || status=$?
seconds=$(( ($(date +%s%N) - started) / 1000000 ))
[ "$status" -eq 0 ] || fail "the batch script exited $status"
log "A: batch script with 12 s left and 6 s trials exited 0 after ${seconds} ms"
grep -q "walltime: less than --trial-time left" "$work/walltime.out" || fail "the worker did not drain on its walltime"
[ "$seconds" -ge 5500 ] || fail "the worker stopped before the walltime drain (${seconds} ms)"
[ "$seconds" -lt 12000 ] || fail "the worker ran into the time limit (${seconds} ms)"
args=$(tr '\n' ' ' <"$work/srun.args")
for expected in "--ntasks-per-node=1" "--cpus-per-task=1" "--walltime 12" "--trial-time 6" \
                "--slots 1" "--drain-timeout 240" "--max-idle 600" "--ca-cert $work/certs/ca.pem"; do
  [[ " $args " == *" $expected "* ]] || fail "srun was not given '$expected': $args"
done
grep -qx "OPENBLAS_NUM_THREADS=1" "$work/srun.env" || fail "the tasks do not get OPENBLAS_NUM_THREADS=1"
check_after_drain A "$work/walltime.out"
completed=$(jobs_query "sum(j['state'] == 'completed' for j in jobs)")
queued=$(jobs_query "sum(j['state'] == 'queued' for j in jobs)")
worker_id=$(grep -Eo "worker slurm-4242-0-[^ ]+" "$work/walltime.out" | head -n1 || true)
log "A: $completed trials completed, $queued left queued, $lost_before lost lease(s) from the race above"
[ "$completed" -gt 0 ] || fail "the worker completed no trial"
[ "$queued" -gt 0 ] || fail "every trial ran: the walltime drain did not stop the worker taking trials"
[ "$(grep -c "attempt 1: RP seed" "$work/walltime.out")" -eq "$completed" ] \
  || fail "the worker started trials it did not complete"
[ -n "$worker_id" ] || fail "the worker id does not name the job, task and node"
log "A: ${worker_id}"

# ---- B: SIGTERM to the batch script -------------------------------------------------------
run_sbatch UNLIMITED "$work/signal.out"
sbatch_pid=${pids[-1]}
wait_for 30 "the worker to take a trial" grep -q "attempt 1: RP seed" "$work/signal.out"
grep -q "no time limit known" "$work/signal.out" || fail "UNLIMITED was not reported as no time limit"
if grep -q -- "--walltime" "$work/srun.args"; then fail "--walltime given without a time limit"; fi
signalled=$(date +%s%N)
kill -TERM "$sbatch_pid"
wait_for 30 "the batch script to end (SIGTERM)" exited "$sbatch_pid"
status=0
wait "$sbatch_pid" || status=$?
[ "$status" -eq 0 ] || fail "the batch script exited $status after SIGTERM"
grep -q "SIGTERM: draining the workers" "$work/signal.out" || fail "the script did not pass SIGTERM on"
grep -q "signal 15: draining" "$work/signal.out" || fail "the worker did not get SIGTERM"
log "B: SIGTERM to the batch script: worker drained, script exited 0 after $(( ($(date +%s%N) - signalled) / 1000000 )) ms"
check_after_drain B "$work/signal.out"

# ---- C: SIGTERM before the workers start --------------------------------------------------
# What Slurm does with --signal=B:TERM@300 when the job starts with less than
# 300 s left: the signal arrives while the script is still reading its time
# left (here: squeue takes 3 s). The script starts no worker and exits 0.
rm -f "$work/srun.args" "$work/squeue.called"
run_sbatch 1:00 "$work/early.out" 3
sbatch_pid=${pids[-1]}
wait_for 10 "the batch script to ask squeue for its time left" test -e "$work/squeue.called"
kill -TERM "$sbatch_pid"
wait_for 30 "the batch script to end (SIGTERM before srun)" exited "$sbatch_pid"
status=0
wait "$sbatch_pid" || status=$?
[ "$status" -eq 0 ] || fail "the batch script exited $status after an early SIGTERM: $(cat "$work/early.out")"
grep -q "SIGTERM before the workers started: starting none" "$work/early.out" \
  || fail "the script did not report the early SIGTERM: $(cat "$work/early.out")"
[ ! -e "$work/srun.args" ] || fail "srun ran after an early SIGTERM"
log "C: SIGTERM while the script read its time left: no worker started, exit 0"
log "PASS"
