"""Monte Carlo runs over a process pool, with a progress line on stderr."""
import os
import sys
import time
import multiprocessing

from ..nav import kernels


def default_procs():
    """Return the number of the machine's cores."""
    return os.cpu_count() or 1


class _Indexed:
    """Picklable ``(i, job) -> (i, fn(job))`` for the pool workers."""

    def __init__(self, fn):
        self.fn = fn

    def __call__(self, item):
        i, job = item
        return i, self.fn(job)


def monte_carlo(fn, jobs, procs=None, progress=True, stream=None):
    """Return ``[fn(job) for job in jobs]``, computed over ``procs`` processes.

    ``fn`` must be picklable (a module-level function) and each job's result depend
    on the job alone (e.g. its seed), so the results are the same for any ``procs``;
    they come back in the order of ``jobs``. ``procs`` None: the machine's cores;
    1 or less: in this process. ``progress``: a progress bar on ``stream``
    (stderr) as runs finish.
    """
    jobs = list(jobs)
    procs = default_procs() if procs is None else int(procs)
    stream = sys.stderr if stream is None else stream
    out = [None] * len(jobs)
    if not jobs:
        return out
    t0 = time.monotonic()
    if procs <= 1:
        for k, job in enumerate(jobs):
            out[k] = fn(job)
            if progress:
                progress_bar(k + 1, len(jobs), t0, stream)
        return out
    # every kernel compiled (or loaded) here before the workers fork: worker processes
    # compiling one cached kernel at once can leave numba's cache broken and segfault
    # (numba issue 4807; seen in a fresh clone's test run)
    kernels.warm_up()
    # workers forked from a clean server process, not from this one: a fork of a
    # process that has run rclpy (a test worker) inherits its middleware threads and
    # objects, and the child segfaulted collecting them (an intermittent test hang)
    with multiprocessing.get_context('forkserver').Pool(procs) as pool:
        for k, (i, res) in enumerate(pool.imap_unordered(_Indexed(fn), enumerate(jobs)),
                                     start=1):
            out[i] = res
            if progress:
                progress_bar(k, len(jobs), t0, stream)
    return out


def progress_bar(done, total, t0, stream=None):
    """Draw a one-line progress bar with the elapsed time and an estimate of what is left."""
    stream = sys.stderr if stream is None else stream
    el = time.monotonic() - t0
    eta = el / done * (total - done) if done else 0.0
    n = int(30 * done / total)
    stream.write(f'\r[{"#" * n}{"." * (30 - n)}] {done}/{total} runs, {el / 60:.1f} min, '
                 f'about {eta / 60:.1f} min left ')
    if done == total:
        stream.write('\n')
    stream.flush()
