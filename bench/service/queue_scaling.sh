#!/usr/bin/env bash
# Issue 28 item 2: the coordinator's CPU per leased and completed job against
# the queue's length, and lease+complete throughput with many fake workers.
# Runs build/bench/service/service_load_bench (one JSON object per run) and
# writes them, one per line, to OUT. Needs about 2.5 GB free in DIR for the
# 1M-job store. Not a test: run it on a quiet machine.
#
#   bench/service/queue_scaling.sh BUILD_DIR OUT [DIR]
set -euo pipefail
build=$1
out=$2
dir=${3:-/tmp}
bench="$build/bench/service/service_load_bench"
: > "$out"
# The disk's fsync rate first: with synchronous=FULL every commit is one.
/usr/bin/python3 - "$dir" >> "$out" <<'PY'
import json, os, sys, time
path = os.path.join(sys.argv[1], "totalgrad_fsync_probe")
fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
count, start = 0, time.time()
while time.time() - start < 5:
    os.write(fd, b"x" * 4096)
    os.fsync(fd)
    count += 1
os.close(fd)
os.remove(path)
print(json.dumps({"fsync_per_second": round(count / (time.time() - start), 1)}))
PY
run() {
  echo "service_load_bench $*" >&2
  "$bench" --dir "$dir" "$@" 2>/dev/null | grep '^{' >> "$out"
}
# CPU per job against the queue: 10 workers run 300 jobs of 2 episodes.
for queued in 1000 10000 100000 1000000; do
  run --workers 10 --jobs 300 --episodes 2 --queued "$queued" --max-seconds 300
done
# Throughput at 1M queued: 100 and 1,000 workers, two episodes per job (the
# initial one and one learned; a sweep needs episodes >= 1 learned).
for workers in 100 1000; do
  run --workers "$workers" --jobs 3000 --episodes 2 --queued 1000000 --max-seconds 120
done
