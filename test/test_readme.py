"""The README's generated tables (sensor grades, node parameters) match the code."""
import re
from pathlib import Path

import numpy as np
import pytest

from sins_align_ros.sim.presets import SENSOR_GRADES

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / 'README.md').read_text()


def _block(tag):
    m = re.search(rf'<!-- {re.escape(tag)} -->\n(.*?)\n<!-- /', README, re.S)
    assert m, f'README has no <!-- {tag} --> block'
    return m.group(1).strip()


def _fmt(x):
    return f'{x:g}'


def grades_table():
    """The sensor-grade table as the README shows it."""
    rows = ['| grade | gyro bias (deg/h) | gyro ARW (deg/rt-h) | gyro Markov (deg/h, tau s) '
            '| accel bias (ug) | accel VRW (ug/rt-Hz) | accel Markov (ug, tau s) |',
            '|---|---|---|---|---|---|---|']
    for name, s in SENSOR_GRADES.items():
        gm = (f'{_fmt(s.gyro_markov_dph)}, {_fmt(s.gyro_markov_tau_s)}'
              if s.gyro_markov_dph else '-')
        am = (f'{_fmt(s.accel_markov_ug)}, {_fmt(s.accel_markov_tau_s)}'
              if s.accel_markov_ug else '-')
        rows.append(f'| `{name}` | {_fmt(np.mean(s.gyro_bias_dph))} | {_fmt(s.gyro_arw_dpsh)} '
                    f'| {gm} | {_fmt(np.mean(s.accel_bias_ug))} | {_fmt(s.accel_vrw_ug_rthz)} '
                    f'| {am} |')
    return '\n'.join(rows)


def test_readme_sensor_grade_table_matches_presets():
    assert _block('grades') == grades_table()


@pytest.mark.parametrize('node', ['simulator_node', 'alignment_node'])
def test_readme_parameter_tables_match_declarations(node):
    pytest.importorskip('rclpy')
    from sins_align_ros.ros.params import markdown_table
    if node == 'simulator_node':
        from sins_align_ros.ros.simulator_node import PARAMS
    else:
        from sins_align_ros.ros.alignment_node import PARAMS
    assert _block(f'params:{node}') == markdown_table(PARAMS), (
        f'README parameter table of {node} is stale; paste markdown_table({node}.PARAMS)')


def test_readme_commands_exist():
    for cmd in ('scripts/demo.sh', 'scripts/test.sh'):
        assert cmd in README and (ROOT / cmd).exists()
    assert 'scripts/test.sh' in (ROOT / '.ci' / 'run').read_text()
