"""Simulation cache: each (scenario, seed) simulated once, later runs load it from disk.

A benchmark that runs several filters (or processes) on the same seeded scenario
simulates it once. The key is the scenario itself (its pickled profile: trajectory,
sensors, GNSS, noise profile, duration...), the seed and the simulator's source, so
a changed profile or simulator never loads a stale file. Files live under
:data:`CACHE_DIR`; :func:`clear` empties it (``bench/moving_base.py`` does at start).
"""
import functools
import hashlib
import os
import pickle
import shutil
import tempfile
from pathlib import Path
from types import SimpleNamespace

from .scenarios import simulate

#: where the simulations are kept
CACHE_DIR = Path(tempfile.gettempdir()) / 'sins_align_bench_cache'
#: what is kept of a simulation: the IMU samples with their truth, the GNSS epochs
IMU_FIELDS = ('t', 'dtheta', 'dv', 'euler', 'v_n', 'pos')
GNSS_FIELDS = ('t', 'lat', 'lon', 'h', 'v_n', 'fix', 'pos_cov', 'vel_cov')
_PACKAGE = Path(__file__).resolve().parents[1]


@functools.lru_cache(maxsize=1)
def _simulator_digest():
    """Hash of the simulator's source (``sim/`` and the ``nav/`` it builds on)."""
    h = hashlib.sha1()
    for sub in ('sim', 'nav'):
        for f in sorted((_PACKAGE / sub).glob('*.py')):
            h.update(f.name.encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def cache_key(sc, seed):
    """File stem of scenario ``sc`` simulated with ``seed``: name, profile hash, seed."""
    h = hashlib.sha1(_simulator_digest().encode())
    h.update(pickle.dumps(sc))
    return f'{sc.name}-{h.hexdigest()[:16]}-{seed}'


def simulate_cached(sc, seed, directory=None):
    """Return the whole run of ``sc`` for ``seed``, simulated once and then loaded.

    A :class:`~types.SimpleNamespace` with ``imu`` (:data:`IMU_FIELDS`) and ``gnss``
    (:data:`GNSS_FIELDS`, or None without a receiver). Safe with several processes
    (each writes a file of its own and renames it into place).
    """
    d = Path(CACHE_DIR if directory is None else directory)
    d.mkdir(parents=True, exist_ok=True)
    f = d / f'{cache_key(sc, seed)}.pkl'
    if f.exists():
        with open(f, 'rb') as fh:
            return pickle.load(fh)
    full = simulate(sc, seed)
    b = SimpleNamespace(
        imu=SimpleNamespace(**{k: getattr(full.imu, k) for k in IMU_FIELDS}),
        gnss=None if full.gnss is None else SimpleNamespace(
            **{k: getattr(full.gnss, k) for k in GNSS_FIELDS}))
    tmp = f.with_suffix(f'.{os.getpid()}.tmp')
    with open(tmp, 'wb') as fh:
        pickle.dump(b, fh)
    os.replace(tmp, f)
    return b


def clear(directory=None):
    """Remove every cached simulation."""
    shutil.rmtree(CACHE_DIR if directory is None else directory, ignore_errors=True)
