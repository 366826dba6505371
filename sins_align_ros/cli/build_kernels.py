"""Build the ahead-of-time kernel module (``_aot_kernels``) with ``numba.pycc``.

    python -m sins_align_ros.cli.build_kernels [PACKAGE_DIR ...]

compiles every kernel declared with a signature
(:data:`~sins_align_ros.compiled.EXPORTS`) into one extension module in
``PACKAGE_DIR`` (default: this package) and writes ``_aot_kernels.sha1``, the
hash of the sources it was built from, which :mod:`~sins_align_ros.compiled` checks
before it uses the module. Needs numba and a C compiler at build time only; the module
itself needs numpy alone. ``scripts/setup.sh`` runs it for the source tree and the colcon
install; where it cannot run, the kernels stay just-in-time compiled (the same numbers, a
slower start). A build tool above the layers it collects kernels from (filters, models,
io, nav), so that ``nav`` imports none of them.

``numba.pycc`` is marked for deprecation by numba (its replacement is not released);
where a numba without it is installed this exits with a message and the package keeps
the just-in-time path. Exit code 0 built, 1 not built (the reason on stderr).
"""
import os
import shutil
import sys
import tempfile
from pathlib import Path


def _compile(workdir):
    """Compile the exported kernels into ``workdir``; returns ``(module file, source hash)``."""
    os.environ['SINS_ALIGN_AOT_BUILD'] = '1'
    import warnings
    from numba.pycc import CC

    from .. import compiled
    from ..filters import cubature  # noqa: F401 (their kernels join EXPORTS on import)
    from ..io import fixed_text  # noqa: F401
    from ..models import large_azimuth, loosely_coupled  # noqa: F401
    from ..nav import kernels  # noqa: F401
    assert compiled.BUILDING_AOT and compiled.AOT is None
    cc = CC(compiled.AOT_MODULE)
    cc.output_dir = str(workdir)
    cc.verbose = False
    for name, func, sig in compiled.EXPORTS:
        cc.export(name, sig)(func)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        cc.compile()
    built = [p for p in Path(workdir).iterdir() if p.name.startswith(compiled.AOT_MODULE)]
    if len(built) != 1:
        raise RuntimeError(f'numba.pycc produced {[p.name for p in built]}')
    return built[0], compiled.source_hash()


def main(argv=None):
    """Build into each package directory given (default: this package); returns 0 or 1."""
    argv = sys.argv[1:] if argv is None else argv
    targets = [Path(a) for a in argv] or [Path(__file__).resolve().parents[1]]
    try:
        with tempfile.TemporaryDirectory() as tmp:
            module, digest = _compile(tmp)
            for package in targets:
                for old in package.glob('_aot_kernels*'):
                    old.unlink()
                shutil.copy2(module, package / module.name)
                (package / '_aot_kernels.sha1').write_text(digest + '\n')
    except Exception as exc:          # no numba.pycc, no compiler, ...: stay just in time
        print(f'sins_align_ros.cli.build_kernels: kernels not compiled ahead of time '
              f'({type(exc).__name__}: {exc}); numba will compile them at first use',
              file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
