"""Named scenarios and the simulation of a whole run."""
from ..align.filter_table import FILTERS
from ..sim.presets import SENSOR_GRADES, scenario
from ..sim.scenario import ScenarioStream


#: every fine filter (and ``auto``) -> a scenario it applies to, for whole-pipeline timings
#: and comparisons (bench/replay_speed.py, test_kernels.py): its paper's (the filter table)
FILTER_SCENARIOS = {**{name: row.scenario for name, row in FILTERS.items()},
                    'auto': 'seed003_car'}


def named(spec, duration=None):
    """Build scenario ``spec``: a preset name, optionally ``name@grade``.

    ``name@grade`` is the preset with the IMU of ``SENSOR_GRADES[grade]`` instead of
    its own (e.g. ``seed001_flight@mems``). ``duration`` (s), when given, shortens
    or lengthens the run.
    """
    base, _, grade = spec.partition('@')
    sc = scenario(base) if duration is None else scenario(base, duration=duration)
    if grade:
        sc.imu = SENSOR_GRADES[grade]
    return sc


def n_samples(sc):
    """Return the number of IMU samples of the whole run of scenario ``sc``."""
    return int(round(sc.duration * sc.imu_rate_hz))


def simulate(sc, seed):
    """Simulate the whole run of scenario ``sc`` for ``seed``.

    Returns a :class:`~sins_align_ros.sim.scenario.SimBlock`: ``imu`` (t, dtheta, dv
    and the truth euler, v_n, pos at each sample) and ``gnss`` (the epochs, or None).
    """
    return ScenarioStream(sc, seed=seed).next_block(n_samples(sc))
