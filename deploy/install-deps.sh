#!/usr/bin/env bash
# Installs the Debian 12 packages totalgrad needs.
#   deploy/install-deps.sh          what building and running the three binaries
#                                   needs (`make demo`, `make build`, containers)
#   deploy/install-deps.sh --test   that plus what only the test suite uses
#                                   (`make test`): browsers, PyTorch, SciPy, ...
# Idempotent: packages already present are skipped, so every `make` target can
# call it. Works as root or through sudo.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libopenblas-dev liblapack-dev
  libboost-dev liblbfgspp-dev libabsl-dev
  # small, and the default configure builds the suites and benchmarks
  libgtest-dev libgmock-dev libbenchmark-dev
  libcli11-dev libtomlplusplus-dev nlohmann-json3-dev libfmt-dev libspdlog-dev
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc
  libsqlite3-dev sqlite3
  libcpp-httplib-dev
  gnuplot-nox
  iproute2 openssl libssl-dev
)

TEST_PACKAGES=(
  # deploy/ file checks (tests/deploy): unit verification, YAML and shell linters
  systemd python3 python3-yaml yamllint shellcheck
  # bench/torch_rp_iteration.py, the PyTorch peer of bench iteration (tests/client/core_commands)
  python3-torch
  # the comparison statistics against SciPy (tests/results/stats_scipy_test.py)
  # and the dashboard in a real headless browser (tests/service/dashboard_browser_test.py)
  python3-scipy chromium chromium-driver python3-selenium
  # tests/service/pandas_view_test.py: the results recipe of docs/results_schema.md
  python3-pandas
  # python/ (`import totalgrad`) and its tests: pybind11, pytest, and the
  # notebook executed by the suite (docs/python-tour.ipynb)
  pybind11-dev python3-dev python3-numpy python3-pytest python3-nbclient python3-nbformat
  python3-ipykernel python3-matplotlib
  # tests/deploy/slurm_cluster_test.sh: the sbatch pool on a real one-node Slurm cluster
  slurm-wlm munge
)

case "${1:-}" in
  --test) PACKAGES+=("${TEST_PACKAGES[@]}") ;;
  "") ;;
  *) echo "install-deps: unknown argument '$1' (expected nothing or --test)" >&2; exit 2 ;;
esac

missing=()
for pkg in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$pkg")
  fi
done

if [ "${#missing[@]}" -eq 0 ]; then
  echo "install-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo"; else
    echo "install-deps: need root or sudo to install: ${missing[*]}" >&2; exit 1
  fi
fi

echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
