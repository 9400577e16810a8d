#!/usr/bin/env bash
# A multi-host run on one machine: four network namespaces made here -- a
# "switch" (a Linux bridge) and three hosts cabled to it by veth pairs: the
# coordinator at 10.203.0.1 and two workers at 10.203.0.11 and .12 -- with TLS
# (deploy/make-dev-certs.sh) and tokens on, the real binaries, and short
# heartbeat/lease settings.
#
#   1. w1 takes a trial; once it has reported an episode, its cable is pulled
#      (its switch port set down) in the middle of the trial.
#   2. Its lease expires on the coordinator; the job is re-queued and w2
#      finishes it.
#   3. The cable is plugged back: w1's late reports for the lost attempt are
#      refused (ABORTED), and nothing it sends for that attempt is stored.
#   4. The final rows are exactly the expected set: every job, every episode,
#      once, each bit-equal to the same trial run in-process.
#
# Addresses are private and exist only inside the namespaces this script
# creates (no route leads out of them); everything is removed on every exit
# path. Needs root for `ip netns`; elsewhere it exits 77 (ctest: skipped).
#
#   netns_multihost_test.sh COORDINATOR_BIN WORKER_BIN CLI_BIN SOURCE_DIR
set -euo pipefail

if [ $# -ne 4 ]; then
  echo "usage: $0 COORDINATOR_BIN WORKER_BIN CLI_BIN SOURCE_DIR" >&2
  exit 2
fi
coordinator_bin=$1 worker_bin=$2 cli_bin=$3 source_dir=$4
here=$(cd "$(dirname "$0")" && pwd)

# fail, log, wait_for, exited.
# shellcheck source=tests/deploy/test_helpers.sh
source "$here/test_helpers.sh"
skip() { echo "SKIP: $*"; exit 77; }

[ "$(id -u)" -eq 0 ] || skip "the multi-host test needs root to create network namespaces (ip netns); it runs in CI, which is root"
command -v ip >/dev/null || skip "ip (iproute2) is not installed"
for tool in openssl python3; do
  command -v "$tool" >/dev/null || fail "$tool is missing: run deploy/install-deps.sh"
done
for binary in "$coordinator_bin" "$worker_bin" "$cli_bin"; do
  [ -x "$binary" ] || fail "$binary is not built"
done

tag="tg$$"                    # unique per run: parallel runs never share a namespace
ns_switch="$tag-switch" ns_coord="$tag-coord" ns_w1="$tag-w1" ns_w2="$tag-w2"
namespaces=()
pids=()
work=$(mktemp -d "/tmp/totalgrad-netns.$$.XXXXXX")

cleanup() {
  local status=$?
  trap - EXIT INT TERM
  # Our own processes, by id; then anything still inside our own namespaces.
  for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null || true; done
  for ns in "${namespaces[@]}"; do
    for pid in $(ip netns pids "$ns" 2>/dev/null); do kill -KILL "$pid" 2>/dev/null || true; done
  done
  for pid in "${pids[@]}"; do wait "$pid" 2>/dev/null || true; done
  for ns in "${namespaces[@]}"; do ip netns delete "$ns" 2>/dev/null || true; done
  if [ "$status" -ne 0 ] && [ "$status" -ne 77 ]; then
    for file in "$work"/*.log; do
      [ -f "$file" ] || continue
      echo "---- $file (last 60 lines)"
      tail -n 60 "$file"
    done
  fi
  if [ -n "${TOTALGRAD_KEEP_NETNS_DIR:-}" ]; then echo "kept $work"; else rm -rf "$work"; fi
  exit "$status"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# ---- the network -------------------------------------------------------------------
# A run killed without its trap (SIGKILL, e.g. a ctest timeout) leaves its
# namespaces, named tg<PID>-*: remove those whose test process is gone.
for ns in $(ip netns list 2>/dev/null | awk '{print $1}' | grep -E '^tg[0-9]+-(switch|coord|w1|w2)$' || true); do
  owner=${ns%%-*}
  owner=${owner#tg}
  if [ "$owner" != "$$" ] && ! kill -0 "$owner" 2>/dev/null; then
    for pid in $(ip netns pids "$ns" 2>/dev/null); do kill -KILL "$pid" 2>/dev/null || true; done
    ip netns delete "$ns" 2>/dev/null && echo "removed $ns, left by an earlier run that was killed"
  fi
done
for dir in /tmp/totalgrad-netns.*.*; do
  owner=${dir#/tmp/totalgrad-netns.}
  owner=${owner%%.*}
  if [ -d "$dir" ] && [[ "$owner" =~ ^[0-9]+$ ]] && [ "$owner" != "$$" ] && ! kill -0 "$owner" 2>/dev/null; then
    rm -rf "$dir"
  fi
done
if ! ip netns add "$ns_switch" 2>"$work/netns.err"; then
  skip "cannot create a network namespace here ($(cat "$work/netns.err")); the test needs root with CAP_SYS_ADMIN, as in CI"
fi
namespaces+=("$ns_switch")
ip -n "$ns_switch" link add br0 type bridge || skip "no bridge support in this kernel"
ip -n "$ns_switch" link set br0 up
ip -n "$ns_switch" link set lo up

add_host() {  # add_host NAMESPACE ADDRESS PORT_NAME
  local ns=$1 address=$2 port=$3
  ip netns add "$ns"
  namespaces+=("$ns")
  ip link add eth0 netns "$ns" type veth peer name "$port" netns "$ns_switch" \
    || skip "cannot create veth pairs here"
  ip -n "$ns_switch" link set "$port" master br0
  ip -n "$ns_switch" link set "$port" up
  ip -n "$ns" addr add "$address/24" dev eth0
  ip -n "$ns" link set eth0 up
  ip -n "$ns" link set lo up
}
coordinator_ip=10.203.0.1
add_host "$ns_coord" "$coordinator_ip" p-coord
add_host "$ns_w1" 10.203.0.11 p-w1
add_host "$ns_w2" 10.203.0.12 p-w2
log "namespaces $ns_switch $ns_coord $ns_w1 $ns_w2: coordinator $coordinator_ip, workers 10.203.0.11, 10.203.0.12"

# ---- TLS, tokens, the coordinator -------------------------------------------------------
bash "$source_dir/deploy/make-dev-certs.sh" "$work/certs" "$coordinator_ip" >/dev/null
ip netns exec "$ns_coord" "$coordinator_bin" --db "$work/coordinator.db" \
  --listen "$coordinator_ip:7070" \
  --tls-cert "$work/certs/server.pem" --tls-key "$work/certs/server.key" \
  --worker-token-file "$work/certs/worker.token" --user-token-file "$work/certs/user.token" \
  --heartbeat-interval 0.2 --lease-timeout 4 --port-file "$work/port" \
  >"$work/coordinator.log" 2>&1 &
coordinator_pid=$!
pids+=("$coordinator_pid")

wait_for 30 "the coordinator to listen" test -s "$work/port"

# The CLI runs on the coordinator's host, over TLS with the user token.
export TOTALGRAD_COORDINATOR="$coordinator_ip:7070" TOTALGRAD_CA_CERT="$work/certs/ca.pem" \
       TOTALGRAD_TOKEN_FILE="$work/certs/user.token"
cli() { ip netns exec "$ns_coord" "$cli_bin" "$@"; }
cli admin health >/dev/null || fail "admin health over TLS failed"

# Two trials of the service tests' slow protocol (with 10 learned episodes): so a cable
# can be pulled in the middle of one; seconds each.
cat >"$work/netns.toml" <<'EOF'
name = "netns"
description = "multi-host test: a worker's cable pulled mid-trial"
max_lost_leases = 5

[grid]
method = ["RP"]
seed = [1, 2]

[protocol]
episodes = 10
policy_steps = 80
particles = 40
eval_rollouts = 2
horizon = 15
EOF
cli sweep submit "$work/netns.toml" >"$work/submit.out" || fail "sweep submit: $(cat "$work/submit.out")"

# One BLAS thread per trial, as every deployment file sets it: `totalgrad
# trial` (the reference below) runs single-threaded, and OpenBLAS's own
# threads change the order of its sums.
start_worker() {  # start_worker NAMESPACE ID SLOTS
  ip netns exec "$1" env OPENBLAS_NUM_THREADS=1 "$worker_bin" --coordinator "$coordinator_ip:7070" \
    --ca-cert "$work/certs/ca.pem" --token-file "$work/certs/worker.token" \
    --slots "$3" --worker-id "$2" --acquire-wait 1 --drain-timeout 10 --state-dir "$work/state" \
    >"$work/$2.log" 2>&1 &
  pids+=("$!")
}

jobs_json() { cli job list --sweep netns -f json; }
# job_query EXPRESSION: whether a Python expression over `jobs` (job list -f json) holds.
job_query() {
  jobs_json | python3 -c "
import json, sys
jobs = json.load(sys.stdin)
sys.exit(0 if ($1) else 1)"
}

start_worker "$ns_w1" w1 1
w1_pid=${pids[-1]}
# w1 has a trial running and at least one episode stored.
wait_for 60 "w1 to report an episode" job_query \
  "any(j['worker_id'] == 'w1' and j['state'] == 'running' and j['episodes_stored'] >= 1 for j in jobs)"
# ---- pull w1's cable in the middle of its trial --------------------------------------------
# At once: on an idle machine an episode of this protocol takes ~0.15 s.
ip -n "$ns_switch" link set p-w1 down
cut_at=$(date +%s%N)
read -r job_w1 progress < <(jobs_json | python3 -c "
import json, sys
running = [(j['job_id'], '%d/%d' % (j['episodes_stored'], j['episodes_expected'])) for j in json.load(sys.stdin) if j['worker_id'] == 'w1' and j['state'] == 'running']
print(*(running[0] if running else ('none', 'none')))")
[ "$job_w1" != none ] || fail "w1's trial ended before its cable was pulled (the trial protocol is too short for this machine)"
# Two slots: w2 runs the other job and still has one free for the re-queued one.
start_worker "$ns_w2" w2 2
w2_pid=${pids[-1]}
log "cable of w1 pulled while job $job_w1 had $progress episodes stored"
stored=${progress%/*} expected=${progress#*/}
[ "$stored" -lt "$expected" ] || fail "job $job_w1 was already complete at the cut ($progress)"

wait_for 60 "job $job_w1's lease to expire" job_query \
  "any(j['job_id'] == $job_w1 and j['lost_leases'] >= 1 for j in jobs)"
expired_at=$(date +%s%N)
log "lease of job $job_w1 lost $(( (expired_at - cut_at) / 1000000 )) ms after the cut (lease timeout 4 s)"

# worker_id names the running attempt's worker only (empty once the job is
# completed), and the re-run from w1's checkpoint can finish between two
# polls: a completed job of 2 or more attempts (`attempts` in job list) is
# the takeover too (w1 is cut off;
# netns_verify.py checks below that w2 stored those rows).
wait_for 60 "w2 to take over job $job_w1" job_query \
  "any(j['job_id'] == $job_w1 and ((j['worker_id'] == 'w2' and j['state'] == 'running') or (j['state'] == 'completed' and j['attempts'] >= 2)) for j in jobs)"
log "job $job_w1 re-run by w2"

# ---- plug it back: w1's late reports are refused -------------------------------------------
ip -n "$ns_switch" link set p-w1 up
restored_at=$(date +%s%N)
refused() {
  grep -Eq "job $job_w1 attempt 1: (the coordinator refused the lease|final report not accepted)" \
    "$work/w1.log"
}
wait_for 90 "w1's late report for job $job_w1 attempt 1 to be refused" refused
log "w1's late report refused $(( ($(date +%s%N) - restored_at) / 1000000 )) ms after the cable was plugged back: $(grep -Eo "job $job_w1 attempt 1: [^;]*" "$work/w1.log" | tail -n1)"

wait_for 120 "both jobs to complete" job_query \
  "len(jobs) == 2 and all(j['state'] == 'completed' for j in jobs)"
log "sweep finished"
cli results export netns -f jsonl >"$work/rows.jsonl"
cli results export netns -f jsonl --all-attempts >"$work/all-rows.jsonl"
cli job list --sweep netns >"$work/jobs.txt"
cat "$work/jobs.txt"

# ---- stop everything the way the deployments do (SIGTERM) ----------------------------------
kill -TERM "$w1_pid" "$w2_pid"
wait_exit() {  # wait_exit PID NAME: bounded wait, then the exit status must be 0
  local pid=$1 name=$2 status=0
  wait_for 30 "$name to exit after SIGTERM" exited "$pid"
  wait "$pid" || status=$?
  [ "$status" -eq 0 ] || fail "$name exited with $status"
  log "$name exited 0 after SIGTERM"
}
wait_exit "$w1_pid" w1
wait_exit "$w2_pid" w2
grep -Eq "worker done: .* [1-9][0-9]* dropped" "$work/w1.log" || fail "w1 does not count the dropped trial"
kill -TERM "$coordinator_pid"
wait_exit "$coordinator_pid" coordinator

# ---- the stored rows ---------------------------------------------------------------------
python3 "$here/netns_verify.py" --db "$work/coordinator.db" --rows "$work/rows.jsonl" \
  --all-rows "$work/all-rows.jsonl" --cli "$cli_bin" --cut-job "$job_w1" --cut-worker w1 \
  --other-worker w2 || fail "stored rows differ from the expected set"
log "PASS: lease lost on the coordinator, job finished by the other worker, late reports refused, rows exact"
