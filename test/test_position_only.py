"""A receiver without velocity (position-only, issue 44): every GNSS-aided path takes it."""
from dataclasses import replace

import numpy as np
import pytest

from sins_align_ros.eval.run import run_pipeline
from sins_align_ros.eval.scenarios import simulate
from sins_align_ros.sim.faults import MessageStream
from sins_align_ros.sim.presets import alignment_params, scenario


@pytest.fixture(scope='module')
def car():
    """120 s of the RTK car with its receiver's velocity switched off."""
    sc = scenario('car_rtk', duration=120.0)
    sc.gnss = replace(sc.gnss, velocity=False)
    return sc, simulate(sc, 5)


@pytest.mark.parametrize('fine_filter', ['auto', 'kf', 'ukf', 'asckf'])
def test_position_only_epochs_feed_the_aided_filters(car, fine_filter):
    sc, data = car
    assert data.gnss.v_n is None
    run = run_pipeline(alignment_params(sc, fine_filter), data)      # use_velocity default
    p = run.pipeline
    assert not p.gnss.vels
    assert p.gnss_counts['used'] > 0
    assert np.all(np.isfinite(run.out.q[run.out.phase == 'fine']))


def test_fault_stream_of_a_position_only_receiver_has_no_velocity(car):
    _, data = car
    s = MessageStream(data)
    assert len(s.gnss['t']) == len(data.gnss.t)
    assert not s.gnss['has_vel'].any()
