"""The import contracts of ``.importlinter`` (docs/design.md#layers), checked with import-linter.

The first test runs them on the source tree. The others run them on a copy of it with
one deliberate break each (a back-up arrow, a circle, rclpy below ``ros``) and check
that the contracts catch it, so a contract that stopped biting would fail here too.
"""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / '.importlinter'
LINT = ('import sys; from importlinter.cli import lint_imports_command; '
        'sys.exit(lint_imports_command())')


def lint_imports(root):
    """Run ``lint-imports`` on the package under ``root``; returns ``(exit code, output)``.

    The package is imported from ``root`` first (not an installed copy on PYTHONPATH).
    """
    pytest.importorskip('importlinter', reason='import-linter not installed '
                        '(scripts/setup.sh --test installs it)')
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(root)] + [p for p in os.environ.get('PYTHONPATH', '').split(os.pathsep) if p]))
    r = subprocess.run([sys.executable, '-c', LINT, '--config', str(CONFIG), '--no-cache',
                        '--no-logo'], cwd=root, env=env, capture_output=True, text=True)
    return r.returncode, r.stdout + r.stderr


def test_the_contracts_hold():
    code, out = lint_imports(ROOT)
    assert code == 0, out
    assert 'Contracts: 7 kept, 0 broken.' in out, out


@pytest.fixture
def tree(tmp_path):
    """Return a copy of the package's Python sources under ``tmp_path`` (the root)."""
    shutil.copytree(ROOT / 'sins_align_ros', tmp_path / 'sins_align_ros',
                    ignore=shutil.ignore_patterns('__pycache__', '*.so', '*.sha1', '*.nbi',
                                                  '*.nbc'))
    return tmp_path


def add_import(tree, module, line):
    """Append ``line`` (an import statement) to ``module`` (a path below the package)."""
    path = tree / 'sins_align_ros' / module
    path.write_text(path.read_text() + '\n' + line + '\n')


@pytest.mark.parametrize('module, line, contract, says', [
    # nav is below align: the layers contract (and a circle, align imports nav)
    ('nav/earth.py', 'from ..align import params', 'Packages in one order',
     'sins_align_ros.nav.earth -> sins_align_ros.align.params'),
    # an input module reaching up to a stage: the rooms of align (and a circle)
    ('align/inputs/imu_input.py', 'from ..stages import fine_stage', 'Inside align',
     'sins_align_ros.align.inputs.imu_input -> sins_align_ros.align.stages.fine_stage'),
    # one engine family importing another
    ('align/engines/robust.py', 'from . import navigation', 'engine families',
     'sins_align_ros.align.engines.robust -> sins_align_ros.align.engines.navigation'),
    # the node reaching past the front door of align
    ('ros/status.py', 'from ..align.engines import aided', 'Only the front door',
     'sins_align_ros.ros.status -> sins_align_ros.align.engines.aided'),
    # a circle inside io (cdr is imported by bag_db3)
    ('io/cdr.py', 'from . import bag_db3', 'No import circles', '.cdr -> .bag_db3'),
    # ROS below ros/
    ('sim/gnss.py', 'import rclpy', 'Only ros imports rclpy',
     'sins_align_ros.sim.gnss -> rclpy'),
])
def test_a_deliberate_break_fails(tree, module, line, contract, says):
    add_import(tree, module, line)
    code, out = lint_imports(tree)
    assert code == 1, out
    broken = ' '.join(out.split('Broken contracts')[1].split())  # lines wrap at 80
    assert contract in broken and says in broken, out
