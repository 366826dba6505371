#!/usr/bin/env bash
# The test command: set up (virtualenv + colcon build, idempotent), then pytest.
# Extra arguments go to pytest (e.g. scripts/test.sh -k mechanization). The tests run on
# SINS_TEST_WORKERS pytest-xdist workers (default 2, the CI machine's cores; 0 runs them in
# this process), which take whole files (--dist loadfile: a module fixture is built once).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash scripts/setup.sh --test
set +u
# shellcheck disable=SC1091
source install/setup.bash
set -u
# one BLAS thread per worker: the filters multiply small matrices, where threads only
# contend for the two cores the workers already use (a 600-s ship test: 3 s of CPU with
# one thread, 35 s with the default)
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}" OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
exec .venv/bin/python -m pytest -n "${SINS_TEST_WORKERS:-2}" --dist loadfile "$@"
