#!/bin/bash
# Issue 29 item 5: how long core/ takes to compile with and without its
# precompiled header (fresh build dirs in /tmp; the step seconds of .ninja_log).
# Build only core/ in a fresh dir with and without the precompiled header; sum ninja log.
set -e
for MODE in ON OFF; do
  D=/tmp/pchbuild-$MODE
  rm -rf $D
  cmake -S /work/main -B $D -G Ninja -DCMAKE_BUILD_TYPE=Release -DTOTALGRAD_PRECOMPILED_HEADERS=$MODE > $D.configure.log 2>&1
  start=$(date +%s.%N)
  flock /tmp/totalgrad-build.lock nice cmake --build $D -j 2 --target totalgrad_core_study totalgrad_core_learner totalgrad_core_diff > $D.build.log 2>&1
  end=$(date +%s.%N)
  python3 - $D $MODE $start $end <<'PY'
import sys
d, mode, start, end = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
total = 0.0; n = 0; by = {}
for line in open(d + "/.ninja_log"):
    if line.startswith("#"): continue
    s, e, _, out, _ = line.rstrip("\n").split("\t")
    sec = (int(e) - int(s)) / 1000.0
    total += sec; n += 1
    key = out.split("/")[1] if "/" in out else out
    by[key] = by.get(key, 0) + sec
print(f"{mode}: wall {end-start:.1f} s, {n} steps, {total:.1f} step s;", {k: round(v,1) for k, v in sorted(by.items(), key=lambda kv: -kv[1])[:12]})
PY
done
