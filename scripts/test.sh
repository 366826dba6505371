#!/usr/bin/env bash
# The test command: set up (virtualenv + colcon build, idempotent), then pytest.
# Extra arguments go to pytest (e.g. scripts/test.sh -k mechanization).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash scripts/setup.sh --test
set +u
# shellcheck disable=SC1091
source install/setup.bash
set -u
exec .venv/bin/python -m pytest "$@"
