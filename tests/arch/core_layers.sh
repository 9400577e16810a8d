#!/usr/bin/env bash
# The plants' side of core/ links no GP (docs/core.md, "Gaussian maths"):
# core/ode, core/gaussian and core/tasks include nothing from core/gp,
# core/pilco, core/policy, core/estimators, core/learner or core/study, and
# their libraries in core/CMakeLists.txt name none of those libraries. So a
# program that simulates a scene and takes its cost's Gaussian expectation
# links Eigen, Boost.Odeint and core/common only.
# Usage: core_layers.sh SOURCE_DIR
set -euo pipefail
source_dir="$1"
failed=0
include='^[[:space:]]*#[[:space:]]*include[[:space:]]*[<"]'
upper='core/(gp|pilco|policy|estimators|learner|study)/'
for folder in ode gaussian tasks; do
  if [ ! -d "$source_dir/core/$folder" ]; then
    echo "FAIL: $source_dir/core/$folder does not exist"; failed=1; continue
  fi
  if hits=$(grep -rEn --include='*.h' --include='*.cc' "${include}${upper}" \
              "$source_dir/core/$folder"); then
    echo "FAIL: core/$folder includes a GP, policy, PILCO or learner header:"; echo "$hits"
    failed=1
  fi
  line=$(grep -E "^totalgrad_core_library\($folder " "$source_dir/core/CMakeLists.txt" || true)
  if [ -z "$line" ]; then
    echo "FAIL: core/CMakeLists.txt declares no library '$folder'"; failed=1
  elif echo "$line" | grep -Eq 'core_(gp|pilco|policy|estimators|learner|study)\b'; then
    echo "FAIL: core/CMakeLists.txt links core/$folder to a GP, policy, PILCO or learner library:"
    echo "$line"; failed=1
  fi
done
if [ "$failed" -ne 0 ]; then exit 1; fi
echo "ok: core/ode, core/gaussian and core/tasks include and link no GP, policy, PILCO or learner code"
