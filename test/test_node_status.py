"""The alignment node's typed status and its /diagnostics over real DDS (issue 43, item 5).

``~/phase``, ``~/reason`` (std_msgs/String), ``~/tilt_ready``, ``~/heading_ready``
(std_msgs/Bool): latched (a late subscriber gets the last value), published on change;
``~/euler``'s yaw NaN while the heading is unknown (a still MEMS IMU without GNSS);
``fine`` with the reason ``no IMU data`` while the input has stopped; the status name with
the node's namespace; messages of at most 200 characters in degrees, whose notes leave
the message after a few seconds (they stay in the values).
"""
import math
import re
import time

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import Vector3Stamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import Imu  # noqa: E402
from std_msgs.msg import Bool, String  # noqa: E402

from conftest import spin_until  # noqa: E402
from sins_align_ros.ros.alignment_node import AlignmentNode  # noqa: E402
from sins_align_ros.io.diagnostic_report import MESSAGE_MAX  # noqa: E402
from sins_align_ros.ros.playback import Player  # noqa: E402
from sins_align_ros.ros.status import LATCHED  # noqa: E402
from sins_align_ros.sim.faults import MessageStream  # noqa: E402
from sins_align_ros.sim.presets import scenario  # noqa: E402
from sins_align_ros.sim.scenario import ScenarioStream  # noqa: E402
from sins_align_ros.units import DEG  # noqa: E402
from test_lifecycle import PARAMS, RELIABLE, RPY, still_imu  # noqa: E402

pytestmark = pytest.mark.ros
WARN, ERROR = DiagnosticStatus.WARN, DiagnosticStatus.ERROR
TYPED = (('phase', String), ('reason', String), ('tilt_ready', Bool), ('heading_ready', Bool))
#: the still, noise-free IMU of test_lifecycle, aligned after 11 s of data (the stage from
#: the 1-s window's end: reprocessing it would start from the prior of a tenth of a second,
#: a heading 1-sigma of 2.6 deg, above the 2-deg bound for long)
STILL = dict(PARAMS, stage_min_duration=5.0, max_stages=1, coarse_reprocess=False)
#: an angle in arcminutes: a digit then a prime
ARCMIN_TEXT = re.compile(r"\d'")


class Probe:
    """A node recording the typed topics, ~/euler and /diagnostics of ``ns/alignment_node``."""

    def __init__(self, ctx, ns='', name='probe'):
        self.node = rclpy.create_node(name, context=ctx)
        self.typed = {k: [] for k, _ in TYPED}
        for key, kind in TYPED:
            self.node.create_subscription(kind, f'{ns}/alignment_node/{key}',
                                          lambda m, k=key: self.typed[k].append(m.data), LATCHED)
        self.euler, self.diag = [], []
        self.node.create_subscription(Vector3Stamped, f'{ns}/alignment_node/euler',
                                      self.euler.append, RELIABLE)
        self.node.create_subscription(DiagnosticArray, '/diagnostics',
                                      lambda m: self.diag.extend(m.status), RELIABLE)

    def last(self):
        return {k: v[-1] if v else None for k, v in self.typed.items()}


class Rig:
    """An alignment node, its probe and an IMU publisher on one executor."""

    def __init__(self, ctx, params=STILL, namespace=None):
        kw = {} if namespace is None else {'namespace': namespace}
        self.node = AlignmentNode(context=ctx, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()], **kw)
        self.ns = namespace or ''
        self.probe = Probe(ctx, self.ns)
        self.pub = self.probe.node.create_publisher(Imu, f'{self.ns}/imu/data_raw', RELIABLE)
        self.ex = SingleThreadedExecutor(context=ctx)
        self.ex.add_node(self.node)
        self.ex.add_node(self.probe.node)
        self.sent = 0
        assert spin_until(self.ex, lambda: self.pub.get_subscription_count() == 1, 10.0)

    def feed(self, n):
        """Publish the next ``n`` still samples, 100 at a time, each lot taken by the node."""
        for k in range(0, n, 100):
            start, m = self.node.received['imu/data_raw'], min(100, n - k)
            for _ in range(m):
                self.sent += 1
                self.pub.publish(still_imu(self.sent))
            assert spin_until(self.ex, lambda: self.node.received['imu/data_raw'] - start == m
                              and not self.node._batch, 10.0)

    def wait(self, predicate, timeout_s=5.0):
        return spin_until(self.ex, predicate, timeout_s)

    def name(self):
        return f'{self.node.get_fully_qualified_name()}: alignment'


def _values(status):
    return {kv.key: kv.value for kv in status.values}


def _check_messages(diag):
    """Every message at most MESSAGE_MAX characters, no angle in arcminutes."""
    assert diag
    assert max(len(d.message) for d in diag) <= MESSAGE_MAX, max(diag, key=lambda d: len(
        d.message)).message
    assert not [d.message for d in diag if ARCMIN_TEXT.search(d.message)]


def test_typed_topics_on_change_latched_and_no_imu_data(ros_context):
    rig = Rig(ros_context)
    p = rig.probe
    assert rig.wait(lambda: p.typed['phase'] == ['waiting'])    # once at start
    assert rig.wait(lambda: p.last() == {'phase': 'waiting', 'reason': 'waiting for IMU data',
                                         'tilt_ready': False, 'heading_ready': False})
    rig.feed(1200)                                  # 12 s: coarse 1 s, aligned at 11 s
    assert rig.node.pipeline.phase == 'aligned'
    assert rig.wait(lambda: p.last()['phase'] == 'aligned')
    # on change only: each phase once, in order, though diagnostics went out every 0.1 s
    assert p.typed['phase'] == ['waiting', 'coarse', 'fine', 'aligned']
    assert p.typed['reason'][:3] == ['waiting for IMU data', 'coarse alignment', 'converging']
    assert p.last() == {'phase': 'aligned', 'reason': '', 'tilt_ready': True,
                        'heading_ready': True}
    assert p.typed['tilt_ready'] == [False, True] and p.typed['heading_ready'] == [False, True]
    # the attitude: a known heading is published
    assert np.abs(np.array([[e.vector.x, e.vector.y, e.vector.z] for e in p.euler[-10:]])
                  - RPY).max() < 0.01 * DEG

    late = Probe(ros_context, name='late_probe')    # transient local: the current values
    rig.ex.add_node(late.node)
    assert rig.wait(lambda: all(late.typed.values()))
    assert late.last() == p.last() and all(len(v) == 1 for v in late.typed.values())

    # the input stops: fine, 'no IMU data', not ready (max(2 s, 3 x 0.1 s) after the last)
    stopped = {'phase': 'fine', 'reason': 'no IMU data', 'tilt_ready': False,
               'heading_ready': False}
    assert rig.wait(lambda: p.last() == stopped, 4.0), p.last()
    assert 2.0 <= time.monotonic() - rig.node._last_imu_wall < 2.0 + 0.1 + 0.5
    assert rig.node.pipeline.phase == 'aligned'     # the pipeline itself is unchanged
    n = len(p.diag)
    assert rig.wait(lambda: len(p.diag) > n)
    st = p.diag[-1]
    assert st.level == ERROR and st.message.startswith('no IMU data for 2.')
    assert _values(st)['phase'] == 'fine' and _values(st)['reason'] == 'no IMU data'
    assert _values(st)['pipeline_phase'] == 'aligned'
    # and back when it resumes
    rig.feed(10)
    assert rig.wait(lambda: p.last() == {'phase': 'aligned', 'reason': '', 'tilt_ready': True,
                                         'heading_ready': True}, 2.0), p.last()
    assert p.typed['phase'] == ['waiting', 'coarse', 'fine', 'aligned', 'fine', 'aligned']
    # (the late probe gets the same publication on its own schedule)
    assert rig.wait(lambda: late.typed['phase'] == ['aligned', 'fine', 'aligned'], 2.0), \
        late.typed['phase']
    n = len(p.diag)
    assert rig.wait(lambda: len(p.diag) > n + 1)
    assert p.diag[-1].level == DiagnosticStatus.OK, p.diag[-1].message
    assert re.fullmatch(r'aligned: 1-sigma roll [0-9.e-]+, pitch [0-9.e-]+, yaw [0-9.e-]+ deg',
                        p.diag[-1].message), p.diag[-1].message
    _check_messages(p.diag)
    rig.ex.shutdown()


def test_status_names_carry_the_namespace(ros_context):
    rigs = [Rig(ros_context, namespace=ns) for ns in ('/robot1', '/robot2')]
    ex = rigs[0].ex
    ex.add_node(rigs[1].node)
    ex.add_node(rigs[1].probe.node)
    assert [r.name() for r in rigs] == ['/robot1/alignment_node: alignment',
                                        '/robot2/alignment_node: alignment']
    assert spin_until(ex, lambda: {d.name for d in rigs[0].probe.diag}
                      == {r.name() for r in rigs}, 5.0), {d.name for d in rigs[0].probe.diag}
    # each namespace has its own typed topics
    assert spin_until(ex, lambda: all(r.probe.typed['phase'] == ['waiting'] for r in rigs), 5.0)
    rigs[0].feed(150)
    assert spin_until(ex, lambda: rigs[0].probe.last()['phase'] == 'fine', 5.0)
    assert rigs[1].probe.typed['phase'] == ['waiting']
    ex.shutdown()


def _mems_stream(duration):
    sc = scenario('static_mems', duration=duration)
    return MessageStream(ScenarioStream(sc, seed=1, imu_rate_hz=100.0).next_block(
        int(duration * 100)))


def test_unknown_heading_publishes_nan_yaw_and_says_why(ros_context):
    """A still MEMS IMU without GNSS (its gyro cannot find north): heading unobservable."""
    s = _mems_stream(30.0)
    node = AlignmentNode(context=ros_context, parameter_overrides=[
        Parameter('coarse_duration', value=10.0), Parameter('diagnostic_period', value=0.2)])
    probe = Probe(ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    ex.add_node(probe.node)
    player = Player(probe.node, node)
    assert spin_until(ex, lambda: player.pub_imu.get_subscription_count() == 1, 10.0)
    assert spin_until(ex, lambda: node.pub_euler.get_subscription_count() == 1, 10.0)
    player.play(ex, s)
    assert spin_until(ex, lambda: 'heading unobservable' in (probe.last()['reason'] or '')
                      and len(probe.euler) >= 1900, 10.0), (probe.last(), len(probe.euler))
    status = node.pipeline.status()
    assert status['heading_observable'] is False and node.pipeline.phase == 'fine'
    assert probe.last()['reason'] == status['not_aligned_reason']
    assert probe.last() == {'phase': 'fine', 'reason': status['not_aligned_reason'],
                            'tilt_ready': True, 'heading_ready': False}
    e = np.array([[m.vector.x, m.vector.y, m.vector.z] for m in probe.euler])
    assert np.isnan(e[:, 2]).all()                  # every published yaw: unknown
    assert np.isfinite(e[:, :2]).all()
    # roll and pitch against the simulator's truth, within 3 published sigmas
    truth = s.truth_euler(float(s.imu['t'][-1]))
    sig = math.radians(status['sigma_roll_deg']), math.radians(status['sigma_pitch_deg'])
    assert np.all(np.abs(e[-1, :2] - truth[:2]) < 3.0 * np.array(sig)), (e[-1], truth, sig)
    # /diagnostics: the reason while it holds, the yaw as unknown, degrees, 200 characters
    n = len(probe.diag)
    assert spin_until(ex, lambda: len(probe.diag) > n + 1, 5.0)
    st = probe.diag[-1]
    assert st.level == WARN
    assert re.match(r'fine, [^:]*heading unobservable[^:]*: 1-sigma roll [0-9.]+, pitch '
                    r'[0-9.]+, yaw unknown deg', st.message), st.message
    _check_messages(probe.diag)
    # the self-check's notes: in the message when they came, then only in the values
    note = 'gyro_arw_dpsh widened'
    assert any(note in d.message for d in probe.diag)
    assert spin_until(ex, lambda: note not in probe.diag[-1].message and len(probe.diag) > n + 5,
                      6.0), probe.diag[-1].message
    assert note in _values(probe.diag[-1])['notes']
    first = next(k for k, d in enumerate(probe.diag) if note in d.message)
    later = [d for d in probe.diag[first:] if note in d.message]
    assert 1 <= len(later) <= 3.0 / 0.2 + 2         # shown for about NOTE_HOLD_S (3 s)
    ex.shutdown()
