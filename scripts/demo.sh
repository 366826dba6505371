#!/usr/bin/env bash
# The demo command: set up (idempotent), then run the simulator and the alignment node
# together over DDS and print the phases and the final error against truth.
# Extra arguments go to sins_align_demo (e.g. --scenario ship_sway --duration 300).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
bash scripts/setup.sh
set +u
# shellcheck disable=SC1091
source install/setup.bash
set -u
exec install/sins_align_ros/lib/sins_align_ros/sins_align_demo "$@"
