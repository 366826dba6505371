#!/usr/bin/env python3
"""The integrity matrix on the old hand-written pool and on Dask, side by side (issue 47).

A fixed subset of ``bench/integrity.py`` (default: every filter and grade, told right, 2
runs per cell) runs in each checkout given by ``--roots``, with ``--jobs 2``, in its own
Python process, one after the other: the old one (``eval/pool.py`` as a multiprocessing
pool of forkserver children, up to commit 8ade444) and this one (a Dask LocalCluster of two
worker processes). Before the timed runs each checkout runs a one-cell warm-up, so that no
timed run compiles a kernel. The page gives the wall time of each and their ratio, and
whether the results (every table row and failing cell: not the timing lines) are the same
line for line.

Usage: python bench/scale_out.py --roots OLD NEW [--labels pool dask] [--jobs 2]
       [--subset "--told right --runs 2"] [--out bench/results/scale_out.md]
(``git worktree add --detach /tmp/old 8ade444`` gives the old checkout; the kernels
compiled ahead of time are copied into it when it has none).
"""
import argparse
import os
import re
import shlex
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from sins_align_ros.eval.markdown import machine_summary, write_markdown  # noqa: E402

SUBSET = '--told right --runs 2'
WARM_UP = ('--filters auto --scenarios static --grades navigation --told right --runs 1 '
           '--duration-scale 0.1')


def run_integrity(root, args, out, jobs):
    """Run ``root``'s bench/integrity.py with ``args`` into ``out``; return the wall time, s."""
    env = dict(os.environ, PYTHONPATH=str(root), OPENBLAS_NUM_THREADS='1', OMP_NUM_THREADS='1')
    env.pop('DASK_SCHEDULER_ADDRESS', None)
    cmd = [sys.executable, str(Path(root) / 'bench' / 'integrity.py'), *shlex.split(args),
           '--jobs', str(jobs), '--commit', 'scale_out', '--out', str(out)]
    t0 = time.monotonic()
    subprocess.run(cmd, cwd=root, env=env, check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    return time.monotonic() - t0


def pipeline_minutes(path):
    """Return the page's pipeline time (min): the runs' own wall times summed, or NaN."""
    m = re.search(r'pipeline time ([0-9.]+) min', Path(path).read_text())
    return float(m.group(1)) if m else float('nan')


def results(path):
    """Return the result lines of an integrity page: table rows and failing cells."""
    return [ln for ln in Path(path).read_text().splitlines() if ln.startswith(('|', '- '))]


def with_kernels(root):
    """Copy this checkout's ahead-of-time kernels into ``root`` if it has none."""
    pkg = Path(root) / 'sins_align_ros'
    if not list(pkg.glob('_aot_kernels*.so')):
        for f in (ROOT / 'sins_align_ros').glob('_aot_kernels*'):
            shutil.copy2(f, pkg / f.name)


def commit_of(root):
    """Return the short commit of checkout ``root`` ('+' when it has uncommitted changes)."""
    def git(*a):
        return subprocess.run(['git', '-C', str(root), *a], capture_output=True,
                              text=True).stdout.strip()
    head = git('rev-parse', '--short', 'HEAD') or '?'
    return head + ('+' if git('status', '--porcelain', '--untracked-files=no') else '')


def main(argv=None):
    """Time both checkouts on the subset and write the page."""
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--roots', nargs=2, required=True, metavar=('OLD', 'NEW'))
    ap.add_argument('--labels', nargs=2, default=['hand-written pool', 'Dask LocalCluster'])
    ap.add_argument('--jobs', type=int, default=2)
    ap.add_argument('--subset', default=SUBSET, help='bench/integrity.py options')
    ap.add_argument('--out', default=str(ROOT / 'bench' / 'results' / 'scale_out.md'))
    args = ap.parse_args(argv)
    roots = [Path(r).resolve() for r in args.roots]
    walls, pages, cpu = [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k, root in enumerate(roots):
            with_kernels(root)
            run_integrity(root, WARM_UP, Path(tmp) / f'warm{k}.md', args.jobs)
        for k, (root, label) in enumerate(zip(roots, args.labels)):
            page = Path(tmp) / f'side{k}.md'
            walls.append(run_integrity(root, args.subset, page, args.jobs))
            pages.append(results(page))
            cpu.append(pipeline_minutes(page))
            print(f'{label}: {walls[-1]:.1f} s', file=sys.stderr)
    same = pages[0] == pages[1]
    cells = sum(1 for ln in pages[1] if ln.startswith('| ') and not ln.startswith('| filter'))
    differ = [f'- `{a}` / `{b}`' for a, b in zip(*pages) if a != b][:10]
    lines = ['# The integrity matrix on the hand-written pool and on Dask (issue 47)', '',
             f'Command: `python bench/scale_out.py --roots {" ".join(args.roots)} '
             f'--jobs {args.jobs} --subset "{args.subset}"`. Machine: {machine_summary()}.',
             '', f'Subset: `python bench/integrity.py {args.subset} --jobs {args.jobs}`, '
             f'{cells} cells, run in each checkout in its own process, one after the other, '
             'after an untimed one-cell warm-up in each (no timed run compiles a kernel); '
             'no simulation cache.', '',
             'Wall time: the whole bench process, start to end. Pipeline time: the runs\' '
             'own wall times summed, as the page gives them (what the workers spent in '
             'the runs).', '',
             '| checkout | commit | runs on | wall time (s) | pipeline time (min) |',
             '|---|---|---|---|---|']
    for root, label, wall, c in zip(roots, args.labels, walls, cpu):
        lines.append(f'| `{root}` | {commit_of(root)} | {label}, {args.jobs} workers '
                     f'| {wall:.1f} | {c:.1f} |')
    lines += ['', f'Ratio {args.labels[1]} / {args.labels[0]}: {walls[1] / walls[0]:.3f}.', '',
              'Results (every table row and failing cell): '
              + ('**identical**, line for line.' if same else '**different**:')]
    lines += differ
    lines += ['', 'The Dask side starts its cluster for the run (spawned workers, each importing '
              'the package: about 2 s) and runs its event loops beside the runs. Dask\'s '
              'default worker settings cost more: its `MALLOC_TRIM_THRESHOLD_=65536` made '
              'each run about 30 % slower, its profiler 1 % and its 20-ms event-loop tick '
              '5 %; the cluster of `sins_align_ros/eval/pool.py` starts without them '
              '(`WORKER_CONFIG`).']
    write_markdown(args.out, lines)
    print(f'wrote {args.out}', file=sys.stderr)
    return 0 if same else 1


if __name__ == '__main__':
    sys.exit(main())
