# Helpers the deploy test scripts share (sourced, not run):
#   fail MESSAGE...            prints FAIL: MESSAGE and exits 1
#   log MESSAGE...             prints MESSAGE after the seconds since sourcing
#   wait_for SECONDS WHAT CMD  runs CMD every 0.2 s until it succeeds; fails
#                              naming WHAT after SECONDS
#   exited PID                 true once PID is gone or a zombie
#   show_logs DIR...           prints the last 40 lines of DIR's *.log and *.out
# shellcheck shell=bash

fail() { echo "FAIL: $*"; exit 1; }

deploy_test_start_ns=$(date +%s%N)
log() {
  local ms=$(( ($(date +%s%N) - deploy_test_start_ns) / 1000000 ))
  printf '[%3d.%d s] %s\n' $(( ms / 1000 )) $(( ms % 1000 / 100 )) "$*"
}

wait_for() {
  local limit=$1 what=$2 deadline
  shift 2
  deadline=$(( $(date +%s) + limit ))
  until "$@"; do
    [ "$(date +%s)" -lt "$deadline" ] || fail "timed out after $limit s waiting for: $what"
    sleep 0.2
  done
}

exited() {
  [ ! -e "/proc/$1/stat" ] || [ "$(sed -E 's/.*\) ([A-Za-z]).*/\1/' "/proc/$1/stat" 2>/dev/null)" = Z ]
}

show_logs() {
  local dir file
  for dir in "$@"; do
    for file in "$dir"/*.log "$dir"/*.out; do
      [ -f "$file" ] || continue
      echo "---- $file (last 40 lines)"
      tail -n 40 "$file"
    done
  done
}

# start_tls_coordinator COORDINATOR_BIN SOURCE_DIR WORK: dev certificates and
# tokens in WORK/certs, a coordinator on 127.0.0.1 (TLS, tokens, heartbeats
# every 0.2 s, leases lost after 5 s) logging to WORK/coordinator.log; its pid
# is added to the caller's `pids`, and TOTALGRAD_COORDINATOR and
# TOTALGRAD_CA_CERT are exported for the worker and the CLI.
start_tls_coordinator() {
  local coordinator_bin=$1 source_dir=$2 work=$3
  bash "$source_dir/deploy/make-dev-certs.sh" "$work/certs" >/dev/null
  "$coordinator_bin" --db "$work/coordinator.db" --listen 127.0.0.1:0 \
    --tls-cert "$work/certs/server.pem" --tls-key "$work/certs/server.key" \
    --worker-token-file "$work/certs/worker.token" --user-token-file "$work/certs/user.token" \
    --heartbeat-interval 0.2 --lease-timeout 5 --port-file "$work/port" >"$work/coordinator.log" 2>&1 &
  pids+=("$!")
  wait_for 30 "the coordinator to listen" test -s "$work/port"
  TOTALGRAD_COORDINATOR="127.0.0.1:$(cat "$work/port")"
  TOTALGRAD_CA_CERT="$work/certs/ca.pem"
  export TOTALGRAD_COORDINATOR TOTALGRAD_CA_CERT
}
