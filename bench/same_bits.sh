#!/usr/bin/env bash
# Do two builds compute the same trials? Runs the same small trial of every
# method (cart-pole swing-up, tip cost, k = 1 and 0.01, 3 learned episodes of
# 40 gradient steps with 60 particles) with the `totalgrad` CLI of each build
# and compares every number both builds report per episode (the episode's
# record and its details but the timings), bit for bit: what the Table-1
# workers must show before they switch to a new build (docs/results/table1.md).
#
#   bench/same_bits.sh OLD/totalgrad NEW/totalgrad [OUT_DIR]
#
# Prints one line per trial and "N of N trials give the same bits"; exits 1
# if any differs (naming the first differing key).
set -euo pipefail
old=${1:?usage: same_bits.sh OLD_CLI NEW_CLI [OUT_DIR]}
new=${2:?usage: same_bits.sh OLD_CLI NEW_CLI [OUT_DIR]}
out=${3:-$(mktemp -d)}
mkdir -p "$out"
total=0; same=0
for noise in 1 0.01; do
  for method in PILCO RP GR LR TP GLR GTP GTP+sn DEL; do
    args=(trial --json --set scene=cartpole-swingup --set cost=tip --set noise_k=$noise
          --set method=$method --set seed=10 --set episodes=3 --set policy_steps=40
          --set particles=60 --set gp_variance_tolerance=0 --set pilco_line_searches=20)
    tag="${method//+/p}-k$noise"
    "$old" "${args[@]}" > "$out/old-$tag.jsonl"
    "$new" "${args[@]}" > "$out/new-$tag.jsonl"
    total=$((total + 1))
    if /usr/bin/python3 - "$out/old-$tag.jsonl" "$out/new-$tag.jsonl" "$tag" <<'PY'
import json, sys
def episodes(path):
    return [json.loads(line) for line in open(path) if '"episode"' in line]
def flat(prefix, value, out):
    if isinstance(value, dict):
        for k, v in value.items():
            if k in ("timing", "cpu_seconds", "optimisation_seconds", "seconds"):
                continue  # times differ from run to run
            flat(prefix + "." + k if prefix else k, v, out)
    else:
        out[prefix] = value
old, new = episodes(sys.argv[1]), episodes(sys.argv[2])
tag = sys.argv[3]
if len(old) != len(new) or not old:
    print(f"{tag}: {len(old)} vs {len(new)} episodes"); sys.exit(1)
compared = 0
for a, b in zip(old, new):
    fa, fb = {}, {}
    flat("", a, fa); flat("", b, fb)
    for key in sorted(set(fa) & set(fb)):
        compared += 1
        if json.dumps(fa[key]) != json.dumps(fb[key]):
            print(f"{tag}: episode {a['episode']}: {key} differs: {fa[key]} vs {fb[key]}"); sys.exit(1)
print(f"{tag}: same bits ({len(old)} episodes, {compared} values; new keys: "
      f"{len(set(fb) - set(fa))})")
PY
    then same=$((same + 1)); fi
  done
done
echo "$same of $total trials give the same bits"
[ "$same" = "$total" ]
