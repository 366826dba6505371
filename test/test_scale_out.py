"""Scale-out on Dask (issue 47 item 4): the bench harness and a fleet of recordings.

The integrity harness (bench/integrity.py) and ``sins_align_replay`` on several inputs run
on a LocalCluster of two worker processes started here, and give the same numbers, byte for
byte, as the same runs in this process. The cluster tests are ``exclusive``: four worker
processes beside another test's would starve the wall-clock paced ones.
"""
import csv
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, load_bench, shared_data
from sins_align_ros.cli import replay_many
from sins_align_ros.cli.replay import main as replay
from sins_align_ros.eval import pool
from sins_align_ros.io.bag import write_scenario_bag
from sins_align_ros.io.results import read_csv
from sins_align_ros.nav import kernels
from sins_align_ros.sim.presets import scenario

START = 1_700_000_000.0


@pytest.fixture(scope='module')
def cluster():
    """A LocalCluster of two one-thread worker processes, as a user would start one."""
    import distributed
    kernels.warm_up()
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=':0') as c:
        yield c


@pytest.fixture(scope='module')
def fleet(tmp_path_factory):
    """A folder of four recordings: two still bags, a moving car bag and a broken .mcap."""
    d = tmp_path_factory.mktemp('fleet')
    for seed in (1, 2):
        write_scenario_bag(d / f'still_{seed}', scenario('static_navigation'), seed=seed,
                           duration=45.0, start_time=START)
    write_scenario_bag(d / 'car', scenario('car_consumer'), seed=3, duration=80.0,
                       start_time=START)
    (d / 'broken.mcap').write_bytes(b'\x89MCAP0\r\n' + b'garbage' * 20)
    (d / 'notes.txt').write_text('not a recording')
    return d


def _summary(path):
    with open(path, newline='') as fh:
        return list(csv.DictReader(fh))


@pytest.mark.exclusive
def test_integrity_harness_on_two_workers_equals_the_runs_in_this_process(cluster, tmp_path,
                                                                          monkeypatch):
    monkeypatch.delenv(pool.SCHEDULER_ENV, raising=False)
    integrity = load_bench('integrity')
    common = ['--filters', 'auto', '--scenarios', 'static', '--grades', 'navigation,mems',
              '--told', 'right', '--runs', '2', '--duration-scale', '0.3', '--commit', 'test']
    here, there = tmp_path / 'here.md', tmp_path / 'there.md'
    assert integrity.main(common + ['--out', str(here)]) == 0
    assert integrity.main(common + ['--out', str(there),
                                    '--scheduler', cluster.scheduler_address]) == 0

    def results(path):      # the table and the failing cells; not the timing lines
        return [ln for ln in path.read_text().splitlines() if ln.startswith(('|', '- '))]
    rows = results(here)
    assert len([r for r in rows if r.startswith('| auto')]) == 2       # two cells
    assert rows == results(there)
    assert f'on the Dask cluster at {cluster.scheduler_address}' in there.read_text()


@pytest.mark.exclusive
def test_fleet_replay_on_two_workers_equals_one_process_and_each_single_replay(
        cluster, fleet, tmp_path, capsys, monkeypatch):
    monkeypatch.delenv(pool.SCHEDULER_ENV, raising=False)
    one, two, local = tmp_path / 'one', tmp_path / 'two', tmp_path / 'local'
    # the broken recording is a fault in its row (exit 1, said even with --quiet); the
    # others still run
    assert replay([str(fleet), '--out', str(one), '--quiet']) == 1
    err = capsys.readouterr().err
    assert 'broken: ' in err and 'not a readable rosbag2' in err and '3 of 4 clean' in err
    assert replay([str(fleet / 'car'), str(fleet / 'still_1'), str(fleet / 'still_2'),
                   str(fleet / 'broken.mcap'), '--out', str(two), '--formats', 'csv,mcap',
                   '--scheduler', cluster.scheduler_address, '--quiet']) == 1
    # --jobs 2: a LocalCluster of its own (eval/pool.py's settings); options may follow
    # the inputs or sit between them
    assert replay([str(fleet / 'car'), '--out', str(local), str(fleet / 'still_1'),
                   '--jobs', '2', '--quiet']) == 0
    rows = _summary(one / 'summary.csv')
    assert [r['result'] for r in rows] == ['broken', 'car', 'still_1', 'still_2']
    # the same files whatever ran them (the summary in the order of the inputs given)
    for name in ('car', 'still_1', 'still_2'):
        assert (one / f'{name}.csv').read_bytes() == (two / f'{name}.csv').read_bytes()
        assert (two / name / f'{name}.mcap').is_file()
    for name in ('car', 'still_1'):
        assert (one / f'{name}.csv').read_bytes() == (local / f'{name}.csv').read_bytes()
    by_name = {r['result']: r for r in _summary(two / 'summary.csv')}
    for r in rows:
        assert by_name[r['result']] == {**r, 'input': by_name[r['result']]['input']}
    assert [r['input'] for r in rows] == [str(fleet / n) for n in (
        'broken.mcap', 'car', 'still_1', 'still_2')]                     # absolute paths
    assert rows[0]['status'] == '1' and 'not a readable rosbag2' in rows[0]['error']
    assert not (one / 'broken.csv').exists()
    # each row is its own single replay's end: final row, first aligned row, warnings
    single = tmp_path / 'single.csv'
    assert replay([str(fleet / 'car'), '--out', str(single), '--quiet']) == 0
    assert single.read_bytes() == (one / 'car.csv').read_bytes()
    for r in rows[1:]:
        assert r['status'] == '0' and r['error'] == ''
        cols = read_csv(one / f'{r["result"]}.csv')
        assert r['phase'] == cols['phase'][-1]
        for k in ('roll_deg', 'pitch_deg', 'yaw_deg', 'heading_deg', 'sigma_yaw_deg'):
            assert float(r[k]) == pytest.approx(cols[k][-1], abs=1e-6), k
        assert float(r['duration_s']) == pytest.approx(cols['t'][-1] - cols['t'][0], abs=1e-6)
        aligned = np.flatnonzero(np.asarray(cols['phase']) == 'aligned')
        assert float(r['time_to_aligned_s']) == pytest.approx(
            cols['t'][aligned[0]] - cols['t'][0], abs=1e-6)
    # the still bags align in their 45 s at 20 s (the coarse window's first check); the
    # MEMS car's self-check widens its model and says so
    assert [float(r['time_to_aligned_s']) for r in rows[2:]] == pytest.approx([20.0, 20.0],
                                                                              abs=0.05)
    assert 'widened' in rows[1]['warnings']


def test_fleet_inputs_names_and_usage_errors(fleet, tmp_path, capsys):
    found = replay_many.recordings([fleet])
    assert [p.name for p in found] == ['broken.mcap', 'car', 'still_1', 'still_2']
    assert replay_many.result_names(found) == ['broken', 'car', 'still_1', 'still_2']
    psins = shared_data('psins_lasergyro.imu')
    with pytest.raises(ValueError, match='one name: psins_lasergyro'):
        replay_many.result_names([psins, psins.with_suffix('.mcap')])
    with pytest.raises(ValueError, match="named 'summary'"):
        replay_many.result_names([psins, tmp_path / 'summary.mcap'])
    # result bags into the inputs' own folder would replace the bag folders
    assert replay([str(fleet), '--out', str(fleet), '--formats', 'csv,mcap']) == 2
    assert 'would replace the input' in capsys.readouterr().err
    assert (fleet / 'car' / 'metadata.yaml').is_file()
    for args, needle in (([str(fleet), '--out', str(tmp_path / 'x.csv')], 'names a folder'),
                         ([str(fleet), '--out', str(tmp_path / 'o'), '--formats', 'csv,pdf'],
                          '--formats takes'),
                         ([str(fleet), '--out', str(tmp_path / 'o'), '--copy-input'],
                          '--copy-input needs result bags'),
                         ([str(fleet), '--out', str(tmp_path / 'o'), '--jobs', '0'],
                          '--jobs must be'),
                         ([str(fleet / 'car'), str(tmp_path / 'nothing'), '--out',
                           str(tmp_path / 'o')], 'no such file'),
                         ([str(tmp_path), '--out', str(tmp_path / 'o')], 'no recording')):
        assert replay(args) == 2, args
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and needle in err[0], err


def test_without_dask_a_parallel_run_is_one_line_naming_the_package(
        fleet, tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, 'distributed', None)      # import fails as if absent
    monkeypatch.delenv(pool.SCHEDULER_ENV, raising=False)
    assert replay([str(fleet), '--out', str(tmp_path / 'o'), '--jobs', '2']) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if 'error' in ln]
    assert len(err) == 1 and 'dask.distributed' in err[0] and 'pip install' in err[0]
    with pytest.raises(pool.MissingDask):
        pool.monte_carlo(abs, [1, 2], procs=2, progress=False)
    assert pool.monte_carlo(abs, [-1, 2], procs=1, progress=False) == [1, 2]   # no Dask
    # one process is this one whatever the environment names; more go to its cluster
    monkeypatch.setenv(pool.SCHEDULER_ENV, 'tcp://192.0.2.1:8786')
    assert pool.monte_carlo(abs, [-1, 2], procs=1, progress=False) == [1, 2]
    assert pool.scheduler_address(None, 2) == 'tcp://192.0.2.1:8786'
    assert pool.scheduler_address('tcp://h:1', 1) == 'tcp://h:1'


def test_the_node_and_a_single_replay_never_import_dask(fleet):
    code = ('import sys; import sins_align_ros.cli.replay, sins_align_ros.ros.alignment_node; '
            'from sins_align_ros.cli.replay import main; '
            f'a = main([{str(shared_data("psins_lasergyro.imu"))!r}, "--duration", "5", '
            '"--out", "/dev/null", "--quiet"]); '
            f'b = main([{str(fleet / "still_1")!r}, "--out", "/dev/null", "--quiet"]); '
            'print(a, b, sorted(m for m in sys.modules '
            'if m.split(".")[0] in ("dask", "distributed")))')
    out = subprocess.run([sys.executable, '-c', code], cwd=ROOT, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == '0 0 []'
