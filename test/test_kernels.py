"""The compiled kernels against the pure-Python reference path, on every fine filter.

``SINS_ALIGN_NO_JIT=1`` makes :mod:`sins_align_ros.compiled`'s kernels plain Python (the
reference, also what runs without numba); a child process runs every fine filter that
way and the results must equal the compiled ones to round-off: those of the
ahead-of-time module (``_aot_kernels``, built by setup) and of numba's just-in-time
path (``SINS_ALIGN_NO_AOT=1``).
"""
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT
from sins_align_ros.eval.scenarios import FILTER_SCENARIOS, named
from sins_align_ros import compiled
from tolerance import roundoff

#: filter -> scenario, run for 150 s: coarse, then fine
CASES = FILTER_SCENARIOS

RUN = """
import json, sys
sys.path.insert(0, {root!r})
import numpy as np
from sins_align_ros.eval.run import run_pipeline
from sins_align_ros.eval.scenarios import named, simulate
from sins_align_ros import compiled
from sins_align_ros.nav import kernels
from sins_align_ros.sim.presets import alignment_params
res = {{'compiled': compiled.COMPILED, 'aot': compiled.AOT is not None}}
for f, name in {cases!r}.items():
    sc = named(name, 150.0)
    out = run_pipeline(alignment_params(sc, f), simulate(sc, 4), block=700).out
    res[f] = [np.nan_to_num(out.q[-1]).tolist(), np.nan_to_num(out.P_phi[-1]).ravel().tolist(),
              str(out.phase[-1])]
print(json.dumps(res))
"""


def _run(no_jit, no_aot=False):
    env = dict(os.environ, OPENBLAS_NUM_THREADS='1')
    env.pop('SINS_ALIGN_NO_JIT', None)
    env.pop('SINS_ALIGN_NO_AOT', None)
    if no_jit:
        env['SINS_ALIGN_NO_JIT'] = '1'
    if no_aot:
        env['SINS_ALIGN_NO_AOT'] = '1'
    out = subprocess.run([sys.executable, '-c', RUN.format(root=str(ROOT), cases=CASES)],
                         env=env, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


@pytest.fixture(scope='module')
def reference():
    """Every filter in plain Python (the slow run, made once for both compiled paths)."""
    return _run(True)


@pytest.mark.skipif(not compiled.COMPILED, reason='numba not installed or switched off')
@pytest.mark.parametrize('no_aot', [False, True], ids=['ahead-of-time', 'just-in-time'])
def test_every_fine_filter_gives_the_same_result_compiled_and_in_pure_python(no_aot,
                                                                             reference):
    ref, fast = dict(reference), _run(False, no_aot)
    assert ref.pop('compiled') is False and fast.pop('compiled') is True
    assert ref.pop('aot') is False and fast.pop('aot') is (compiled.AOT is not None and not no_aot)
    for f in CASES:
        (q0, P0, ph0), (q1, P1, ph1) = ref[f], fast[f]
        assert ph0 == ph1 and ph0 != 'coarse', f
        # 150 s of IMU samples (n = 150 x rate): a strapdown step (~50 operations on unit
        # attitudes, test_mechanization.STEP_OPS) and at most one filter step (~100 on P's
        # size) each, passed on with gain at most 1 (orthonormal products; a stable filter's
        # (I - K H) F): n x 150 operations (tolerance.py)
        n_ops = int(150.0 * named(CASES[f], 150.0).imu_rate_hz) * 150
        assert np.abs(np.array(q0) - np.array(q1)).max() <= roundoff(n_ops), f
        P0, P1 = np.array(P0), np.array(P1)
        assert np.abs(P0 - P1).max() <= roundoff(n_ops, np.abs(P0).max()), f


WARM = """
import sys
sys.path.insert(0, {root!r})
from sins_align_ros.align import pipeline  # what the node has imported when it warms up
from sins_align_ros import compiled
from sins_align_ros.nav import kernels
kernels.warm_up()
def count():
    return {{d.py_func.__qualname__: len(d.signatures) for d in compiled.DISPATCHERS}}
before = count()
from sins_align_ros.eval.run import run_pipeline
from sins_align_ros.eval.scenarios import named, simulate
from sins_align_ros.sim.presets import alignment_params
for f, name in (('reduced7', 'static_navigation'), ('stationary12', 'static_navigation'),
                ('asckf', 'seed000_case1'), ('kf', 'seed003_car')):
    sc = named(name, 65.0)
    for block in (1, 10):
        run_pipeline(alignment_params(sc, f), simulate(sc, 1), block=block)
print(before == count(), before, count())
"""


@pytest.mark.skipif(not compiled.COMPILED, reason='numba not installed or switched off')
def test_warm_up_compiles_every_signature_the_pipeline_uses():
    """A live node warms up before it subscribes; a signature left out compiles mid-data.

    (A read-only ``dt`` from ``np.broadcast_to`` made numba compile a second
    ``strapdown_run`` at the node's first block: a second of stall at 1000 messages/s, and
    the end-to-end node test saw an IMU gap.)
    """
    out = subprocess.run([sys.executable, '-c', WARM.format(root=str(ROOT))], check=True,
                         capture_output=True, text=True,
                         env=dict(os.environ, OPENBLAS_NUM_THREADS='1',
                                  SINS_ALIGN_NO_AOT='1')).stdout
    assert out.startswith('True'), out


IMPORTS = """
import sys
sys.path.insert(0, {root!r})
from sins_align_ros.cli import replay  # noqa: F401  (the replay's and the pipeline's imports)
from sins_align_ros import compiled
from sins_align_ros.nav import kernels
import numpy as np
from sins_align_ros.nav.mechanization import Strapdown
kernels.warm_up()
z = np.zeros((2500, 3))                 # past the re-orthonormalisation every 1000 samples
Strapdown(np.eye(3), np.zeros(3), 0.8, 0.0, 0.0).run(z, z, 0.01)
print(compiled.AOT is not None, 'numba' in sys.modules, 'scipy.linalg' in sys.modules)
"""


@pytest.mark.skipif(shutil.which('cc') is None, reason='no C compiler: no ahead-of-time build')
def test_setup_built_the_ahead_of_time_kernels_and_a_replay_imports_neither_numba_nor_scipy():
    """Issue 22: numba's import and first call (with scipy.linalg) were 0.7 s of each start.

    LAPACK inside a compiled kernel (an SVD) imports scipy.linalg at its first call,
    0.15 s: hence the 2500 samples.
    """
    assert compiled.AOT is not None, 'scripts/setup.sh did not build _aot_kernels'
    assert {name for name, _, _ in compiled.EXPORTS} <= set(dir(compiled.AOT))
    out = subprocess.run([sys.executable, '-c', IMPORTS.format(root=str(ROOT))], check=True,
                         capture_output=True, text=True,
                         env=dict(os.environ, OPENBLAS_NUM_THREADS='1')).stdout
    assert out.split() == ['True', 'False', 'False'], out


def test_a_stale_ahead_of_time_module_is_not_used(monkeypatch):
    """Built from other sources (an edit since setup): the just-in-time path instead."""
    with monkeypatch.context() as m:
        m.setattr(compiled, 'source_hash', lambda: '0' * 40)
        assert compiled._load_aot() is None
    monkeypatch.setenv('SINS_ALIGN_NO_AOT', '1')
    assert compiled._load_aot() is None
