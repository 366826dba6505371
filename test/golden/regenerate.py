"""Regenerate the golden replay CSVs of test/test_golden.py from the code of this checkout.

    source install/setup.bash
    .venv/bin/python test/golden/regenerate.py [CASE ...]

RUN THIS ONLY WHEN A CHANGE IS MEANT TO CHANGE RESULTS (a fix, a new model, a changed
default), never to make test_golden.py pass after a refactor: the goldens are the
evidence that a refactor left the numbers alone. Say in the commit message that the
goldens were regenerated and why the results changed.

The cases are the table in ``cases.py`` (shared with the test). Without arguments all
goldens are rewritten; with case names only those. The checkout this file lives in is
put first on sys.path, so its ``sins_align_ros`` is the one run (the path is printed).
Each run is checked to pass through the phases its case expects (nothing is written
unless all do), and the CPU time per case is printed. Needs the recordings of
../shared/data (or --data DIR).
"""
import argparse
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / 'test')]

from golden.cases import BY_NAME, CASES, run_case  # noqa: E402

#: where the tests find the recordings (test/conftest.py SHARED_DATA)
SHARED_DATA = ROOT.parent / 'shared' / 'data'


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('cases', nargs='*', metavar='CASE',
                    help=f'case names (default: all): {", ".join(BY_NAME)}')
    ap.add_argument('--data', type=Path, default=SHARED_DATA,
                    help=f'folder of the real recordings (default {SHARED_DATA})')
    args = ap.parse_args()
    unknown = [n for n in args.cases if n not in BY_NAME]
    if unknown:
        ap.error(f'unknown case {unknown[0]!r}; known: {", ".join(BY_NAME)}')
    import sins_align_ros
    from sins_align_ros.io.results import read_csv
    print(f'code: {Path(sins_align_ros.__file__).parent}')

    def data(name):
        p = args.data / name
        if not p.exists():
            sys.exit(f'regenerate.py: {p} not present (--data names the recordings folder)')
        return p

    chosen = [BY_NAME[n] for n in args.cases] if args.cases else list(CASES)
    total, outs = 0.0, []
    with tempfile.TemporaryDirectory(prefix='sins_golden_') as work:
        for case in chosen:                     # all runs first: nothing is written
            c0 = time.process_time()            # unless every case passes its check
            out = run_case(case, work, data)
            cpu = time.process_time() - c0
            total += cpu
            phases = [str(p) for p in dict.fromkeys(read_csv(out)['phase'])]
            if tuple(phases) != case.expect:
                sys.exit(f'regenerate.py: {case.name} went through {phases}, the case '
                         f'expects {list(case.expect)}; no golden written')
            outs.append((case, out, phases, cpu))
        for case, out, phases, cpu in outs:
            case.golden.write_bytes(out.read_bytes())
            print(f'{case.name}: {case.golden.stat().st_size / 1024:.0f} KiB, '
                  f'phases {"/".join(phases)}, {cpu:.1f} s CPU')
    print(f'{len(chosen)} goldens written, {total:.1f} s CPU')


if __name__ == '__main__':
    main()
