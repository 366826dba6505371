"""sins_align_ros: initial alignment of a strapdown inertial navigation system for ROS 2.

Layers, top to bottom (docs/design.md; checked by the contracts in ``.importlinter``):
``ros`` and ``cli``, ``eval``, ``io``, ``align`` and ``sim``, ``models``, ``nav`` and
``filters``, ``units``. Only ``ros`` imports rclpy or message packages.
"""

__version__ = '0.1.0'


def single_thread_blas():
    """Limit the BLAS thread pools to one thread unless the user chose otherwise.

    Called by the processes this package starts (``cli``, ``ros``), before numpy is
    imported; not on import of the package, whose users keep their own settings. The
    numerics are small matrices (at most 18 x 18) that a BLAS never splits across
    threads, so its pool only costs: numpy's OpenBLAS starts one thread per core at
    import (55 ms of a replay's start on 2 cores) and the threads spin between calls
    (a whole core for a node at 200 Hz).
    """
    import os
    for var in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
        os.environ.setdefault(var, '1')
