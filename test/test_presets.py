"""Every YAML in config/ is measured against the node's defaults (issue 44, item 7).

``bench/presets.py`` runs each alignment preset and the node's defaults on scenarios of
the preset's kind and writes ``bench/results/presets.md``; its Verdicts table names each
file with a verdict and the digest of the parameters it was measured with. These checks
are cheap (no run): a preset added or changed without being measured, or measured and
found no better than the defaults, fails here. (test_nodes.py loads each file into its
node over DDS.)
"""
from pathlib import Path

import pytest

from conftest import load_bench
from sins_align_ros.align.param_text import load_yaml
from sins_align_ros.align.params import split_node_params
from sins_align_ros.sim.presets import SCENARIOS

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / 'bench' / 'results' / 'presets.md'
YAMLS = sorted((ROOT / 'config').glob('*.yaml'))


def bench_module():
    """Return bench/presets.py as a module."""
    return load_bench('presets')


def verdicts():
    """File name -> (verdict, digest) from the results page's Verdicts table."""
    section = RESULTS.read_text().split('## Verdicts', 1)[1]
    out = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip('|').split('|')]
        if len(cells) == 3 and cells[0].endswith('.yaml'):
            out[cells[0]] = (cells[1], cells[2])
    return out


def node_of(path):
    """The node a config file is for, from its name."""
    return 'simulator_node' if path.name.startswith('simulator_') else 'alignment_node'


def test_config_files_exist():
    assert any(p.name.startswith('alignment_') for p in YAMLS)


@pytest.mark.parametrize('path', YAMLS, ids=lambda p: p.name)
def test_every_config_file_is_measured_and_not_worse_than_defaults(path):
    """Named in presets.md with the digest of its current parameters, verdict not "no better"."""
    table = verdicts()
    assert path.name in table, f'{path.name} is not in {RESULTS.name}: run bench/presets.py'
    verdict, digest = table[path.name]
    assert digest == bench_module().params_digest(path, node_of(path)), (
        f'{path.name} changed since it was measured: re-run bench/presets.py')
    assert not verdict.startswith('no better'), f'{path.name}: {verdict}'
    if node_of(path) == 'simulator_node':
        assert verdict.startswith('simulator data')
    elif bench_module().installation_only(path.name):
        assert verdict == bench_module().INSTALLATION_ONLY
    else:
        assert verdict == 'better'


@pytest.mark.parametrize('path', [p for p in YAMLS if node_of(p) == 'alignment_node'],
                         ids=lambda p: p.name)
def test_alignment_presets_have_scenarios_and_valid_parameters(path):
    """The benchmark knows the preset's scenarios; the pipeline takes its parameters."""
    mod = bench_module()
    assert path.name in mod.SCENARIOS_OF
    for key in mod.SCENARIOS_OF[path.name][0]:
        if key != 'fog_mems':
            assert mod.scenario_of(key).duration > 0.0
    values, node_only = split_node_params(load_yaml(path))
    assert values and set(node_only) <= {'odom_frame_id', 'base_frame_id', 'imu_frame_id'}


@pytest.mark.parametrize('path', [p for p in YAMLS if node_of(p) == 'simulator_node'],
                         ids=lambda p: p.name)
def test_simulator_presets_name_known_scenarios(path):
    assert load_yaml(path, 'simulator_node')['scenario'] in SCENARIOS
