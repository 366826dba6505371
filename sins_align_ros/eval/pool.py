"""Monte Carlo runs and fleets of recordings on Dask (dask.distributed), with tqdm progress.

One front door, :func:`monte_carlo`: ``[fn(job) for job in jobs]`` computed

- in this process (one job at a time) when ``procs`` is 1 or less and no scheduler is named;
- on a :class:`distributed.LocalCluster` of ``procs`` one-thread worker processes started for
  the call (the default on more than one core);
- on a running cluster, given its scheduler's address (``scheduler='tcp://host:8786'``;
  or, when more than one process is asked for, Dask's own ``DASK_SCHEDULER_ADDRESS``).

Dask is needed only for the last two: the node and a single replay never import it, and a
user who asks for ``--jobs`` or ``--scheduler`` without it installed gets
:class:`MissingDask`, a one-line message naming the package.

Kept from the hand-written pool this replaces (session 48's ``eval/pool.py``):

- every compiled kernel is compiled (or loaded) in this process before workers start:
  processes compiling one cached kernel at once can leave numba's cache broken and
  segfault (numba issue 4807; seen in a fresh clone's test run);
- the workers do not inherit this process: Dask's nanny starts them with the ``spawn``
  method (``distributed.worker.multiprocessing-method``, set here), so a test process
  that has run rclpy does not pass its middleware threads to a child (a fork of one
  segfaulted collecting them: an intermittent test hang).

Results come back in the order of ``jobs`` and depend on the job alone (its seed), never
on which worker ran it or how many there were.
"""
import logging
import os
import sys

from tqdm import tqdm

from ..nav import kernels

#: the environment variable Dask's Client reads for a scheduler address
SCHEDULER_ENV = 'DASK_SCHEDULER_ADDRESS'


#: Dask settings of the LocalCluster, whatever a user's Dask configuration says:
#: workers spawned (a fork inherits rclpy's threads); and without Dask's
#: ``MALLOC_TRIM_THRESHOLD_=65536``, which made each run about 30 % slower (a 200-s ASCKF
#: run, best of three, 0.88 s in this process against 1.14 s on a Dask worker and 1.17 s in
#: this process started with that variable: the filters allocate many small arrays, and
#: glibc then gives the memory back and asks for it again all the time)
WORKER_CONFIG = {'distributed.worker.multiprocessing-method': 'spawn',
                 'distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_': None,
                 # the dashboard's statistical profiler (a stack sample every 10 ms): the
                 # dashboard needs bokeh, not installed, and it cost 1 % of a run
                 'distributed.worker.profile.enabled': False,
                 # the event loop's 20-ms tick (its blocked-loop watch) takes the GIL from
                 # the run 50 times a second: 0.90-0.93 s against 0.85 s with a 1-s tick,
                 # 0.88-0.91 s in this process (the same ASCKF run, one worker)
                 'distributed.admin.tick.interval': '1s'}


class MissingDask(RuntimeError):
    """Several processes or a cluster were asked for, and dask.distributed is not installed."""


def default_procs():
    """Return the number of the machine's cores."""
    return os.cpu_count() or 1


def scheduler_address(scheduler=None, procs=2):
    """Return the cluster to run on, or None for a LocalCluster or this process.

    ``scheduler`` when given; else ``$DASK_SCHEDULER_ADDRESS`` when more than one process
    is asked for (``procs`` > 1): one process always means this one, whatever the
    environment says, and a parallel run goes to the cluster the environment names
    instead of a local one.
    """
    if scheduler:
        return scheduler
    return (os.environ.get(SCHEDULER_ENV) or None) if procs > 1 else None


def _distributed():
    """Import dask.distributed, or raise :class:`MissingDask` naming the package to install."""
    try:
        import distributed
    except ImportError:
        raise MissingDask('parallel runs (--jobs N > 1, --scheduler) need dask.distributed: '
                          'pip install "dask[distributed]" (apt: python3-distributed)') from None
    return distributed


def open_client(procs, scheduler=None):
    """Return a connected :class:`distributed.Client` and the cluster it started (or None).

    The cluster of :func:`scheduler_address`; else a LocalCluster of ``procs`` one-thread
    worker processes (its HTTP server on a free port: two clusters at once do not contend
    for Dask's 8787), started after the kernels are compiled here. Close
    both when done (:func:`close_client`).
    """
    distributed = _distributed()
    address = scheduler_address(scheduler, procs)
    if address:
        return distributed.Client(address, set_as_default=False), None
    kernels.warm_up()
    import dask
    environ = dict(os.environ)
    try:
        with dask.config.set(WORKER_CONFIG):
            cluster = distributed.LocalCluster(n_workers=int(procs), threads_per_worker=1,
                                               processes=True, dashboard_address=':0',
                                               silence_logs=logging.ERROR)
    finally:        # the nanny sets its workers' variables in this process's environment
        os.environ.clear()
        os.environ.update(environ)
    return distributed.Client(cluster, set_as_default=False), cluster


def close_client(client, cluster):
    """Close a client of :func:`open_client` and the cluster it started."""
    client.close()
    if cluster is not None:
        cluster.close()


def monte_carlo(fn, jobs, procs=None, progress=True, stream=None, scheduler=None):
    """Return ``[fn(job) for job in jobs]``, in job order; see the module's docstring.

    ``fn`` must be picklable by cloudpickle (a module-level function; one of a script's
    ``__main__`` goes by value) and its result depend on the job alone, so the results are
    the same for any ``procs``. ``procs`` None: the machine's cores; 1 or less: in this
    process (unless ``scheduler`` is given). ``scheduler``: a running cluster's address
    (for ``procs`` > 1 the default is ``$DASK_SCHEDULER_ADDRESS``; :func:`scheduler_address`).
    ``progress``: a tqdm bar on ``stream`` (stderr) as runs finish.
    """
    jobs = list(jobs)
    procs = default_procs() if procs is None else int(procs)
    out = [None] * len(jobs)
    if not jobs:
        return out
    bar = tqdm(total=len(jobs), unit='run', file=sys.stderr if stream is None else stream,
               disable=not progress, mininterval=1.0, dynamic_ncols=True)
    with bar:
        address = scheduler_address(scheduler, procs)
        if procs <= 1 and not address:
            for k, job in enumerate(jobs):
                out[k] = fn(job)
                bar.update()
            return out
        client, cluster = open_client(min(procs, len(jobs)), address)
        try:
            distributed = _distributed()
            futures = client.map(fn, jobs, pure=False)
            index = {f.key: k for k, f in enumerate(futures)}
            for fut in distributed.as_completed(futures, loop=client.loop):
                out[index[fut.key]] = fut.result()
                bar.update()
        finally:
            close_client(client, cluster)
    return out
