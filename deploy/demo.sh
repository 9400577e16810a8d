#!/usr/bin/env bash
# The main job on the embedded single-machine default: `totalgrad run` starts a
# coordinator on a local SQLite file (out/run/) and one worker per core on
# loopback, runs deploy/sweeps/demo.toml, prints the results table and where
# the plot went, and stops them. Without the service build it falls back to a
# short in-process RP trial.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR="${1:-build}"
if [ -x "$BUILD_DIR/server/totalgrad-coordinator" ]; then
  exec "$BUILD_DIR/client/totalgrad" run deploy/sweeps/demo.toml
fi
exec "$BUILD_DIR/client/totalgrad" trial --scene cartpole-swingup --cost angle --noise-k 1 \
  --method RP --seed 1 --episodes 3 --policy-steps 100 --particles 100 --eval-rollouts 10
