#!/usr/bin/env bash
# The main job on the embedded single-machine default. Until the service
# lands this is a short in-process RP trial on the swing-up.
set -euo pipefail
BUILD_DIR="${1:-build}"
if [ -x "$BUILD_DIR/server/totalgrad-coordinator" ] && [ -f deploy/sweeps/demo.toml ]; then
  exec "$BUILD_DIR/client/totalgrad" run deploy/sweeps/demo.toml
fi
exec "$BUILD_DIR/client/totalgrad" trial --scene cartpole-swingup --cost angle --noise-k 1 \
  --method RP --seed 1 --episodes 3 --policy-steps 100 --particles 100 --eval-rollouts 10
