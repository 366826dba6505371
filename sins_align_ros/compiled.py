"""Compilation of the package's numeric kernels (numba), with a pure-Python fallback.

The ground floor of the package beside :mod:`.units`: ``nav``, ``filters``, ``models``
and ``io`` declare their inner loops with :func:`jit` and import nothing of one another
for it (docs/design.md#import-contracts).

Three ways the same functions run, chosen once at import:

1. **Ahead of time** (:mod:`~sins_align_ros.cli.build_kernels`): the kernels compiled by
   ``numba.pycc`` into the extension module ``_aot_kernels`` of this package when it is
   set up. Loading it takes a millisecond and does not import numba, whose import and
   first compiled call (its type registries, and ``scipy.linalg`` for its BLAS check) cost
   about 0.7 s of every process start (issue 22). Used only while ``_aot_kernels.sha1``
   beside it matches the kernels' sources (:func:`source_hash`): an edit makes it stale
   and the next path is taken until it is built again (``SINS_ALIGN_NO_AOT=1`` skips it).
2. **Just in time**: numba compiles at the first call and caches on disk
   (``cache=True``: beside the source, or in the user's cache directory when that is
   read-only, numba's own fallback), so only the first start on a machine compiles.
3. **Plain Python**: without numba, or with ``SINS_ALIGN_NO_JIT=1`` in the environment
   (correct and slow; the reference the tests hold the compiled paths to).

Kernels called from Python are declared with their numba signature
(``@jit(sig=...)``): the ahead-of-time module exports exactly those; helpers only
called by kernels are compiled into them.
"""
import functools
import hashlib
import os
from pathlib import Path

import numpy as np

#: the kernels' sources (package-relative): what the ahead-of-time module is built from
AOT_SOURCES = ('compiled.py', 'nav/kernels.py', 'nav/earth.py', 'filters/cubature.py',
               'models/large_azimuth.py', 'models/loosely_coupled.py', 'io/fixed_text.py')
#: the ahead-of-time module's name (in this package) and its source hash file
AOT_MODULE = '_aot_kernels'
_PACKAGE = Path(__file__).resolve().parent
_NO_JIT = os.environ.get('SINS_ALIGN_NO_JIT', '') == '1'
#: set by :mod:`~sins_align_ros.cli.build_kernels` while it compiles: every kernel a plain
#: numba function, no cache
BUILDING_AOT = os.environ.get('SINS_ALIGN_AOT_BUILD', '') == '1'


def source_hash():
    """SHA-1 (hex) of :data:`AOT_SOURCES`' contents, in order."""
    h = hashlib.sha1()
    for rel in AOT_SOURCES:
        h.update((_PACKAGE / rel).read_bytes())
    return h.hexdigest()


def _load_aot():
    """Return the ahead-of-time module if it is there and built from these sources.

    ``SINS_ALIGN_NO_AOT=1`` in the environment skips it (the just-in-time path, tested).
    """
    if _NO_JIT or BUILDING_AOT or os.environ.get('SINS_ALIGN_NO_AOT', '') == '1':
        return None
    stamp = Path(__file__).with_name(AOT_MODULE + '.sha1')
    try:
        if stamp.read_text().strip() != source_hash():
            return None
        from . import _aot_kernels as module
    except (OSError, ImportError):
        return None
    return module


AOT = _load_aot()
numba = None
if AOT is None and not _NO_JIT:
    try:                                 # pragma: no cover - depends on the install
        import numba
    except ImportError:                  # pragma: no cover
        numba = None

#: the kernels are compiled (ahead of time, or by numba; not switched off)
COMPILED = AOT is not None or numba is not None


#: every kernel compiled just in time through :func:`jit`, in order (empty ahead of time)
DISPATCHERS = []
#: ``(export name, Python function, numba signature)`` of every declared kernel
EXPORTS = []
#: first calls registered by other modules' kernels (:func:`warms_up`)
_WARM_UPS = []


def export_name(func):
    """Name of ``func`` in the ahead-of-time module: ``<module>__<function>``."""
    return f'{func.__module__.rsplit(".", 1)[-1]}__{func.__name__}'


def jit(func=None, *, sig=None):
    """Compile ``func``: ahead of time, with numba (cached on disk), or leave it Python.

    ``sig``: the numba signature of a kernel called from Python (exported by the
    ahead-of-time module); without it ``func`` is a helper that kernels call, compiled
    into them (plain Python when the ahead-of-time module is used).
    """
    if func is None:
        return functools.partial(jit, sig=sig)
    if sig is not None:
        EXPORTS.append((export_name(func), func, sig))
    if AOT is not None:
        return getattr(AOT, export_name(func)) if sig is not None else func
    if numba is not None:
        dispatcher = numba.njit(cache=not BUILDING_AOT, nogil=True)(func)
        DISPATCHERS.append(dispatcher)
        return dispatcher
    return func


def warms_up(func):
    """Register ``func()`` (a module's kernels' first calls) with :func:`warm_up`."""
    _WARM_UPS.append(func)
    return func


def kernel_array(a):
    """Return ``a`` as a C-contiguous, writeable float64 array (a copy only when it is not one).

    The form of an array argument of the kernels called from Python: numba compiles a
    separate version for read-only arrays (a broadcast one is), and the ahead-of-time
    module takes float64 only.

    ``np.require(a, float, ['C', 'W'])``'s result, without its cost (several
    microseconds, at every block of ``Strapdown.run``).
    """
    a = np.asarray(a, dtype=float)
    if a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.array(a, dtype=float, order='C')


def run_warm_ups():
    """Run the first calls every module registered with :func:`warms_up` (those imported)."""
    for first_calls in _WARM_UPS:
        first_calls()
