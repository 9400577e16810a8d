#!/bin/bash
# The accuracy gate for the low-rank variance: same build, option off vs on.
cd /work/main
OUT=docs/results/speed/lowrank/gate
T=$1
for k in 1 0.01; do
  S=docs/results/speed/snapshots/snap_rp_seed5_k$k.json
  for m in RP GR LR TP GLR GTP GTP+sn DEL; do
    tag=$(echo $m | tr '+' 'p')
    [ -f $OUT/k${k}_${tag}_exact.json ] || build/client/totalgrad bench gradients --snapshot $S --episode 15 --method $m --replicates 20 --gp-variance-tolerance 0 --out $OUT/k${k}_${tag}_exact.json
    build/client/totalgrad bench gradients --snapshot $S --episode 15 --method $m --replicates 20 --gp-variance-tolerance $T --out $OUT/k${k}_${tag}_tol$T.json
    /usr/bin/python3 bench/accuracy_gate.py $OUT/k${k}_${tag}_tol$T.json $OUT/k${k}_${tag}_exact.json | sed "s/^{/{\"k\": $k, \"tolerance\": $T, /" >> $OUT/gate_results.jsonl
  done
done
