"""Lint with ament's settings: flake8 (ament_flake8 configuration) and pep257 (ament_pep257)."""
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PATHS = [str(ROOT / p) for p in ('sins_align_ros', 'test', 'launch', 'bench', 'setup.py')
         if (ROOT / p).exists()]
# ament_flake8's default configuration (ament_lint/ament_flake8/configuration/ament_flake8.ini)
FLAKE8_ARGS = ['--max-line-length=99',
               '--extend-ignore=B902,C816,D100,D101,D102,D103,D104,D105,D106,D107,D203,D212,'
               'D404,I202,W503,W504']
# ament_pep257: the pep257 convention plus its default ignore list
PEP257_IGNORE = 'D100,D101,D102,D103,D104,D105,D106,D107,D203,D212,D404'


def test_flake8():
    pytest.importorskip('flake8', reason='flake8 not installed (setup.sh --test installs it)')
    r = subprocess.run([sys.executable, '-m', 'flake8', *FLAKE8_ARGS, *PATHS],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def test_pep257():
    pytest.importorskip('pydocstyle', reason='pydocstyle not installed')
    r = subprocess.run([sys.executable, '-m', 'pydocstyle', '--convention=pep257',
                        f'--add-ignore={PEP257_IGNORE}',
                        '--match=(?!test_|conftest).*\\.py', *PATHS],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
