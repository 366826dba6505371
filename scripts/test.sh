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
exec .venv/bin/python -m pytest -n "${SINS_TEST_WORKERS:-2}" --dist loadfile "$@"
